// Paper sheets: the system that creates, attaches and steps the sheets of a world.
#pragma once

#include "paper/sheet.hpp"
#include "sim/host_contacts.hpp"
#include "sim/step_context.hpp"

#include <functional>
#include <utility>
#include <vector>

namespace tearables::detail {

class PaperSystem {
public:
    PaperId add(const PaperDesc& desc, const RigidTable& rigids);
    void remove(PaperId id);
    std::vector<PaperId> ids() const;
    bool contains(PaperId id) const {
        return id.index < sheets_.size() && sheets_[id.index].alive && sheets_[id.index].generation == id.generation;
    }
    /// The id of the sheet in `slot` (its current generation).
    PaperId idAt(std::size_t slot) const { return PaperId{static_cast<std::uint32_t>(slot), sheets_[slot].generation}; }
    PaperSheet& get(PaperId id);
    const PaperSheet& get(PaperId id) const;
    PaperView view(PaperId id) const;

    void attachToPoint(PaperId id, std::uint32_t vertex, const Vec3& point);
    void attachToRigid(PaperId id, std::uint32_t vertex, RigidId body, const Vec3& local, const RigidTable& rigids);
    void movePin(PaperId id, std::uint32_t vertex, const Vec3& point);
    /// Frees a vertex; a Release event goes to `events` when it was held.
    void release(PaperId id, std::uint32_t vertex, EventCause cause, double time, std::int64_t step, std::vector<Event>& events);
    void applyForce(PaperId id, std::uint32_t vertex, const Vec3& force);

    /// Drops every glue to `body` (Release events, cause BodyRemoved).
    void releaseBody(RigidId body, double time, std::int64_t step, std::vector<Event>& events);
    bool usesBody(RigidId body) const;
    /// Bounds of every live sheet grown by its radius and its travel in a step of h.
    void bounds(double h, const Vec3& gravity, std::vector<std::pair<Vec3, Vec3>>& out) const;

    /// One step of every sheet: velocities (implicit Jacobi or explicit), rigid contacts,
    /// positions, creases and hinges, tears, the finite check.
    void step(RigidTable& rigids, const StepContext& ctx, const HostContacts& host, std::vector<Event>& events);
    /// Contacts of the last step, per the query's object order (for tests).
    const std::vector<PointContact>& lastContacts() const { return contacts_; }
    /// Wall time of the sheets' stages in the last step, s.
    const PaperTimes& lastTimes() const { return times_; }

private:
    friend struct WorldAccess;  // snapshots read and replace the sheets (src/world/snapshot.cpp)
    void collideBodies(RigidTable& rigids, const PaperStep& ctx, const HostContacts& host);
    void solve(const RigidTable& rigids, const PaperStep& ctx);
    void enforceContacts(RigidTable& rigids, const PaperStep& ctx);
    void tension(const PaperStep& ctx);
    void positions(RigidTable& rigids, const PaperStep& ctx);
    void crease(const PaperStep& ctx, std::vector<Event>& events);
    void tearAndCheck(const StepContext& step, const PaperStep& ctx, std::vector<Event>& events);
    std::vector<PaperSheet> sheets_;
    PointQuery query_;
    std::vector<std::uint32_t> query_sheet_;
    std::vector<PointContact> contacts_;
    std::vector<std::vector<PointContact>> per_sheet_;
    std::vector<std::vector<std::uint32_t>> glued_;      // per sheet, the bodies it is glued to (sorted)
    std::vector<double> share_;                          // per body, how many vertices it is coupled to
    std::vector<std::vector<BodyCoupling>> couplings_;   // per sheet
    PaperTimes times_;
};

}  // namespace tearables::detail
