// Contacts between rigid bodies as a member of an island (sim/island.hpp): the contacts of
// one pair of bodies (or of a body and a surface only the host moves), solved in the same
// Newton system as the strings that hold the bodies, so that no solver undoes another.
#pragma once

#include "island/body_pair.hpp"

#include <cstddef>
#include <vector>

namespace tearables::detail {

class BodyContactMember final : public BodyPairMember {
public:
    /// The contacts [first, first + count) of `contacts`, all between body a and body b
    /// (b fixed when it is not movable). `contacts` must outlive the solve: finish()
    /// writes each contact's normal force into it.
    void start(std::vector<BodyContact>& contacts, std::size_t first, std::size_t count, const RigidTable& rigids,
               const StepContext& ctx);

    void condense(bool fresh) override;
    bool addPredictedContacts() override;
    double energy(double alpha) const override;
    double apply(double alpha, const std::vector<int>& slot, const Eigen::VectorXd& displacement) override;
    bool frictional() const override { return frictional_; }
    double reweigh() override;
    void finish(int iterations) override;

private:
    /// One contact, linearised where the bodies were when the solve started: for the
    /// bodies' displacements d = (u, theta) its gap is g + ja . d_a + jb . d_b (the
    /// rigid-body contact Jacobian, as Bullet's solver uses it), its slip
    /// P (motion + sa d_a + sb d_b) with P the tangent projector.
    struct Row {
        Vec6 ja, jb;
        Mat36 sa, sb;
        Mat3 tangent;
        Vec3 motion;
        double gap = 0.0;
        double allow = 0.0;   ///< m: the overlap this step may leave (the start's, in part)
        double mu = 0.0;
        double weight = 0.0;  ///< lagged friction's w = mu F / max(|slip|, eps)
        double force = 0.0;   ///< N: the normal force where the pass started
        bool held = false;    ///< in the Newton system (touching, or the step runs into it)
    };
    double gapAt(const Row& r, const Vec6& da, const Vec6& db) const { return r.gap + r.ja.dot(da) + r.jb.dot(db); }
    Vec3 slipAt(const Row& r, const Vec6& da, const Vec6& db) const { return r.tangent * (r.motion + r.sa * da + r.sb * db); }

    std::vector<BodyContact>* contacts_ = nullptr;
    std::size_t first_ = 0;
    bool frictional_ = false;
    double stiffness_ = 0.0;  ///< N/m: under a load F the contact gives way by F / k only
    std::vector<Row> rows_;
};

/// The pairs of `contacts` that the island solve keeps: contacts of a movable body (with
/// a movable or a fixed one), finite, with unit normals, grouped by pair in the order
/// given. Others are dropped; a contact whose a is fixed and b movable is turned round.
void prepareBodyContacts(std::vector<BodyContact>& contacts, const RigidTable& rigids);

}  // namespace tearables::detail
