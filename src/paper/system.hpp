// Paper sheets: the small system World::Impl owns and calls from World::step.
#pragma once

#include "paper/sheet.hpp"

#include <functional>
#include <utility>
#include <vector>

namespace tearables::detail {

/// Finds the contacts of a PointQuery (World::Impl::findPointContacts, which checks the host's answer).
using PointContactFinder = std::function<void(const PointQuery&, std::vector<PointContact>&)>;

class PaperSystem {
public:
    PaperId add(const PaperDesc& desc, const RigidTable& rigids);
    void remove(PaperId id);
    std::vector<PaperId> ids() const;
    bool contains(PaperId id) const { return id.index < sheets_.size() && sheets_[id.index].alive; }
    PaperSheet& get(PaperId id);
    const PaperSheet& get(PaperId id) const;
    PaperView view(PaperId id) const;

    void attachToPoint(PaperId id, std::uint32_t vertex, const Vec3& point);
    void attachToRigid(PaperId id, std::uint32_t vertex, RigidId body, const Vec3& local, const RigidTable& rigids);
    void movePin(PaperId id, std::uint32_t vertex, const Vec3& point);
    /// Frees a vertex; a Release event goes to `events` when it was held.
    void detach(PaperId id, std::uint32_t vertex, EventCause cause, double time, std::int64_t step, std::vector<Event>& events);
    void applyForce(PaperId id, std::uint32_t vertex, const Vec3& force);

    /// Drops every glue to `body` (Release events, cause BodyRemoved).
    void forgetBody(RigidId body, double time, std::int64_t step, std::vector<Event>& events);
    bool usesBody(RigidId body) const;
    /// Bounds of every live sheet grown by its radius and its travel in a step of h.
    void bounds(double h, const Vec3& gravity, std::vector<std::pair<Vec3, Vec3>>& out) const;

    /// One step of every sheet: velocities (implicit Jacobi or explicit), rigid contacts,
    /// positions, creases and hinges, tears, the finite check.
    void step(const PaperStep& ctx, RigidTable& rigids, const PointContactFinder& find, std::vector<Event>& events);
    /// Contacts of the last step, per the query's object order (for tests).
    const std::vector<PointContact>& lastContacts() const { return contacts_; }
    /// Wall time of the sheets' stages in the last step, s.
    const PaperTimes& lastTimes() const { return times_; }

private:
    friend struct WorldAccess;  // snapshots read and replace the sheets (src/world/snapshot.cpp)
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
