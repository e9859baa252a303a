// The island solve: members (strings) coupled through movable bodies, grouped into
// islands and each solved as one system with its bodies' six unknowns (sim/island.hpp).
#pragma once

#include "island/body_contacts.hpp"
#include "island/body_joints.hpp"
#include "sim/body_motion.hpp"
#include "sim/island.hpp"

#include <Eigen/Cholesky>

#include <cstddef>
#include <cstdint>
#include <vector>

namespace tearables::detail {

class ThreadPool;

class IslandSolver final : public IslandSolve {
public:
    void solve(const std::vector<IslandMember*>& members, RigidTable& rigids, const StepContext& ctx) override;
    bool hasOwnMembers() const override { return !body_contacts_.empty() || !body_joints_.empty(); }
    void restart() override;
    void keepOutcome() override;
    void restoreOutcome() override;
    bool converged() const override;
    /// The host's contacts between bodies for this step (ContactProvider::findBodyContacts):
    /// those the solve can keep (prepareBodyContacts) join the islands of their bodies.
    void setBodyContacts(const std::vector<BodyContact>& contacts, const RigidTable& rigids);
    /// The host's joints between bodies for this step (ContactProvider::findBodyJoints):
    /// those the solve can keep (prepareBodyJoints) join the islands of their bodies.
    void setBodyJoints(const std::vector<BodyJoint>& joints, const RigidTable& rigids);
    /// This step's body contacts, with the normal force each carried (0 before the solve).
    const std::vector<BodyContact>& bodyContacts() const { return body_contacts_; }
    /// The joints kept (prepareBodyJoints), with the impulses the last solve gave (BodyJoint).
    const std::vector<BodyJoint>& bodyJoints() const { return body_joints_; }
    /// Forgets the last step's islands (a step may have none to solve).
    void clearReports() { reports_.clear(); }
    /// The islands of the last solve, in the order of their first member.
    const std::vector<IslandSummary>& reports() const { return reports_; }

private:
    struct Island {
        std::vector<IslandMember*> members;
        std::vector<std::vector<int>> slots;  ///< per member: its bodies' island slots (kept: reused)
        std::size_t used_slots = 0;
        std::vector<RigidId> bodies;
    };
    void group(const std::vector<IslandMember*>& members, const RigidTable& rigids);
    IslandSummary solveIsland(Island& island, RigidTable& rigids, const StepContext& ctx);
    /// Assembles the island's Newton system (fresh: a new iteration) and solves it into du_.
    void solveSystem(Island& island, bool fresh);
    /// The bodies' inertia's part of the island's right-hand side, -M u / h^2, into rhs_.
    void inertiaRhs(const Island& island);
    void addSoftening(const Island& island);
    bool solveChord(Island& island);
    double energy(const Island& island, double alpha);
    /// fn(k) for each member k of the island, on the pool where the world has one.
    template <class Fn>
    void forMembers(const Island& island, Fn&& fn);
    /// Moves the island's bodies by alpha du_.
    void moveBodies(Island& island, RigidTable& rigids, const StepContext& ctx, double alpha);
    /// Returns whether the island took the warm start.
    bool warmStart(Island& island, RigidTable& rigids, const StepContext& ctx);

    std::vector<BodyContact> body_contacts_;      ///< grouped by pair (prepareBodyContacts)
    std::vector<double> last_forces_;             ///< their forces as the step gave them (restart)
    std::vector<Vec6> last_displacement_;         ///< per body of the table: the last solve's displacement
    bool resume_ = false;                         ///< the next solve starts where the last ended (restart)
    /// keepOutcome's copies.
    struct Outcome {
        std::vector<BodyContact> contacts;
        std::vector<BodyJoint> joints;
        std::vector<IslandSummary> reports;
        std::vector<Vec6> displacement;
    };
    Outcome kept_;
    std::vector<BodyContactMember> body_members_;  ///< one per pair; kept from step to step
    std::vector<BodyJoint> body_joints_;           ///< prepareBodyJoints
    std::vector<BodyJointMember> joint_members_;   ///< one per joint; kept from step to step
    std::vector<IslandMember*> all_members_;       ///< the strings', then the pairs'
    std::vector<Island> islands_;  ///< kept from step to step: a step does not allocate
    std::size_t used_ = 0;         ///< of which this step's
    std::vector<IslandSummary> reports_;
    std::vector<std::uint32_t> parent_;  ///< union-find over body slots of the table
    std::vector<int> island_of_;  ///< per table body: island index, or -1
    std::vector<int> slot_of_;    ///< per table body: its slot in its island, or -1
    std::vector<Mat6> hint_normal_;  ///< per body: the warm start's least-squares matrix
    Eigen::VectorXd hint_rhs_;       ///< and right-hand side (6 per body)
    // One island's solve.
    std::vector<Mat6> mass_;          ///< per body: generalised mass
    std::vector<Mat3> softening_;     ///< per body: the members' turning softening (addSoftening)
    Eigen::VectorXd displacement_;    ///< per body: (u, theta) from where the solve started
    Eigen::VectorXd pass_start_;      ///< displacement_ where the pass started
    Eigen::MatrixXd system_;
    Eigen::VectorXd rhs_, du_;
    Eigen::LDLT<Eigen::MatrixXd> ldlt_;
    double inv_h2_ = 0.0;
    ThreadPool* pool_ = nullptr;
    std::vector<double> accepted_energy_;  ///< the pass's last energies, for the line search
    std::vector<double> member_value_;  ///< per member: its energy or move, summed in order
};

}  // namespace tearables::detail
