// Strings that touch each other, one of them in an island (holding or touching a movable
// body), as one member of that island (sim/island.hpp): the bodies' unknowns join the
// strings' joint solve (cluster_solve.cpp), so the contacts between the strings and the
// bodies' reactions are solved together instead of with the bodies held still.
//
// Each string is a StringIslandMember (its chain A_i, its couplings B_i to its bodies, its
// bodies' block D_i); the string-string contacts add rank-1 terms U K U^T on the strings'
// unknowns. With A = diag(A_i) and Z = A^-1 U, C = K^-1 + U^T Z, the Woodbury identity
// gives the strings' system's inverse, (A + U K U^T)^-1 = A^-1 - Z C^-1 Z^T, and so the
// Schur complement on the bodies and its right-hand side (y = A^-1 r):
//     S  = sum_i (D_i - B_i^T A_i^-1 B_i) + W C^-1 W^T,      W = B^T Z,
//     rs = sum_i (r_b,i - B_i^T y_i)      + W C^-1 (U^T y),
// each member's own condensed system plus one correction of rank at most the number of
// contact directions; back substitution: dx = dx0 - Z C^-1 (U^T dx0), dx0 each member's
// own, A_i^-1 (r_i - B_i du).
#pragma once

#include "sim/island.hpp"
#include "string/string_state.hpp"

#include <memory>
#include <vector>

namespace tearables::detail {

class ClusterIslandMember final : public IslandMember {
public:
    ClusterIslandMember();
    ~ClusterIslandMember() override;
    ClusterIslandMember(ClusterIslandMember&&) noexcept;
    ClusterIslandMember& operator=(ClusterIslandMember&&) noexcept;

    /// The cluster's strings and contacts (as solveStringCluster takes them), which must
    /// outlive the island's solve. False where no pair touches: then it is no member.
    bool start(const std::vector<StringState*>& strings, std::vector<StringPairContact>& contacts, RigidTable& rigids,
               const StepContext& ctx, ClusterScratch& work);

    const std::vector<RigidId>& bodies() const override;
    bool touchesBodies() const override { return true; }
    void addWarmHints(const std::vector<int>&, std::vector<Mat6>&, Eigen::VectorXd&) const override {}
    void warmStep(const std::vector<int>&, const Eigen::VectorXd&) override {}
    void holdStep(const std::vector<int>& slot, const Eigen::VectorXd& du) override;
    void beginPass() override;
    void condense(bool fresh) override;
    void addTo(const std::vector<int>& slot, Eigen::MatrixXd& system, Eigen::VectorXd& rhs) const override;
    void addTurningSoftening(const std::vector<int>& slot, std::vector<Mat3>& softening) const override;
    void backSubstitute(const std::vector<int>& slot, const Eigen::VectorXd& du) override;
    bool addPredictedContacts() override;
    double energy(double alpha) const override;
    double apply(double alpha, const std::vector<int>& slot, const Eigen::VectorXd& displacement) override;
    bool frictional() const override { return true; }
    double reweigh() override;
    void finish(int iterations) override;
    std::size_t stringCount() const override;

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

}  // namespace tearables::detail
