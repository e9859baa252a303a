// What the island members between two bodies share (body contacts, joints): a member with
// no unknowns of its own whose energy is a function of one movable body's displacement
// and, where it moves, another's; its Newton system a 12 x 12 Hessian and gradient in the
// two bodies' (u, theta).
#pragma once

#include "sim/body_motion.hpp"
#include "sim/island.hpp"

#include <vector>

namespace tearables::detail {

/// The penalties' stiffness over the heavier body's m / h^2 (a joint's axes: over its largest
/// moment of inertia / h^2): a load F gives way by F / k, for a body resting on another
/// g h^2 / kPairStiffnessFactor (1.7 um at h = 1/240 s). The same factor as a string's
/// contacts (string/strain_limit.cpp).
constexpr double kPairStiffnessFactor = 100.0;
/// Convergence: the touching or joined points' relative move in an iteration over this (m).
constexpr double kPairMoveTolerance = 1e-7;

/// How the island keeps a pair between body a and body b (either may be invalid: a frame
/// only the host moves): Drop it (a body the table no longer holds, neither body movable,
/// or one body twice), Keep it as it is, or Swap its sides so that a is the movable body.
enum class PairOrder { Drop, Keep, Swap };
PairOrder orderPair(RigidId a, RigidId b, const RigidTable& rigids);

class BodyPairMember : public IslandMember {
public:
    const std::vector<RigidId>& bodies() const override { return bodies_; }
    bool touchesBodies() const override { return true; }
    void addWarmHints(const std::vector<int>&, std::vector<Mat6>&, Eigen::VectorXd&) const override {}
    void warmStep(const std::vector<int>&, const Eigen::VectorXd&) override {}
    void beginPass() override {}
    void addTo(const std::vector<int>& slot, Eigen::MatrixXd& system, Eigen::VectorXd& rhs) const override;
    void backSubstitute(const std::vector<int>& slot, const Eigen::VectorXd& du) override;
    /// Not a string: the islands' reports count strings only.
    bool isBodyContacts() const override { return true; }

protected:
    /// Starts a solve between body a and body b (b fixed when not movable, or invalid).
    void startPair(RigidId a, RigidId b, const RigidTable& rigids);
    /// The bodies' displacements taken from the island's (after apply's step).
    void takeDisplacements(const std::vector<int>& slot, const Eigen::VectorXd& displacement);

    std::vector<RigidId> bodies_;
    bool b_moves_ = false;
    Vec6 disp_a_ = Vec6::Zero(), disp_b_ = Vec6::Zero();  ///< from where the solve started
    Vec6 du_a_ = Vec6::Zero(), du_b_ = Vec6::Zero();      ///< the island's step
    Eigen::Matrix<double, 12, 12> hessian_;
    Eigen::Matrix<double, 12, 1> gradient_;
};

}  // namespace tearables::detail
