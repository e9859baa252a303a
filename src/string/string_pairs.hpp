// String-string and self collision (Strings Sec. 6): every segment is a capsule, and two
// capsules overlap when their axes come closer than the sum of the radii. The pairs are
// found on the segments swept over the step (a box tree per string, collision/grid.hpp),
// and the strings that touch are solved together (solveStringCluster): one Newton method
// on the sum of their energies, contact penalties and Coulomb friction on the contact
// points' relative motion. A mass-weighted projection after the tension stage removes
// what overlap that solve left.
#pragma once

#include "base/thread_pool.hpp"
#include "collision/grid.hpp"
#include "sim/rigid_table.hpp"
#include "sim/step_context.hpp"
#include "string/cluster_member.hpp"
#include "string/string_state.hpp"

#include <cstdint>
#include <utility>
#include <vector>

namespace tearables::detail {

/// The string-string contacts of a step and what persists of them between steps.
class StringPairs {
public:
    /// After every string's own strain limit, before the tension stage: finds the pairs
    /// and solves each cluster of touching strings jointly, except those with a string in
    /// an island (`in_island`, per string slot), which startCoupled hands to the islands.
    void couple(std::vector<StringState>& strings, RigidTable& rigids, const StepContext& ctx,
                const std::vector<std::uint8_t>& in_island);
    /// The clusters couple left to the islands, each started as one island member (its
    /// strings' contacts and the bodies' unknowns solved together); `solved` gets 1 at the
    /// slots of their strings. Empty where no such cluster has a pair that touches.
    const std::vector<IslandMember*>& startCoupled(RigidTable& rigids, const StepContext& ctx, std::vector<std::uint8_t>& solved);
    /// After the islands solved startCoupled's members: their contacts' forces and normals.
    void finishCoupled();
    /// Marks (1 at its slot) every string of a cluster that couple left to the islands.
    void markCoupled(std::vector<std::uint8_t>& mark) const;
    /// Instead of finishCoupled, where the islands' solve with the clusters did not
    /// converge and was undone: each such cluster solved as couple solves the others
    /// (the bodies held where the islands left them).
    void solveCoupledHeld(RigidTable& rigids, const StepContext& ctx);
    /// After the tension stage: projects away the overlap the joint solve left, marks the
    /// colliding particles and keeps the warm start of the next step.
    void finish(std::vector<StringState>& strings);

    /// Test switches: whole node pairs of the tree dropped (nodesSeparationNeeded), straight
    /// strings' self search skipped (selfPairFree), every joint step sparse.
    bool node_pruning = true;
    bool straight_strings_skip = true;
    bool sparse_joint_steps = false;
    /// The last search's node pairs dropped whole (0 when the tree did not run).
    std::size_t lastNodeRejects() const { return tree_searched_ ? tree_.lastNodeRejects() : 0; }
    /// Strings whose self search selfPairFree skipped in the last search.
    std::size_t lastSelfFreeStrings() const;
    /// The pairs of the last swept search that were not dropped.
    const std::vector<SegmentPair>& lastSearchPairs() const { return grid_pairs_; }

private:
    friend struct WorldAccess;  // snapshots keep the warm start and the deep pairs

    // Per live string: where its particles and segments start in the search's arrays, its
    // thickest radius, largest |x|_1 and |x_prev|_1, finite radii, and selfPairFree's sums:
    // the least advance of a segment along the string's chord at the start of the step
    // (less a rounding margin; -1 where the chord has no direction), and the largest
    // change of travel from one particle to the next.
    struct PairString {
        std::uint32_t string;
        std::size_t particle_base, segment_base;
        double thickest;
        double extent;
        bool finite;
        double advance = -1.0;
        double shear = 0.0;
    };
    // Strings that touch, their pairs (cluster-local string numbers) and the pairs' indices.
    struct Cluster {
        std::vector<StringState*> strings;
        std::vector<StringPairContact> contacts;
        std::vector<std::size_t> index;
        ClusterScratch scratch;  // kept so that a running step does not allocate
        bool coupled = false;    // a string of it is in an island: solved there
        ClusterIslandMember member;
    };
    static constexpr std::uint8_t kPairDropped = 0, kPairDeep = 1, kPairContact = 2;

    void findPairs();
    void searchTree(std::uint32_t skip);
    void sortContacts();
    template <bool fill>
    void scanString(PairString& ps);
    bool selfPairFree(const PairString& ps, std::uint32_t skip) const;
    std::uint8_t judgePair(const SegmentPair& pair, StringPairContact& c) const;
    bool surelyDropped(std::uint32_t i, std::uint32_t j) const;
    double nodesSeparationNeeded(const ChainTree::NodeBounds& a, const ChainTree::NodeBounds& b) const;
    void warmStart();
    std::size_t groupClusters();
    StringPairContact localContact(const StringPairContact& c) const;
    void solveClusters(std::size_t count, RigidTable& rigids, const StepContext& ctx);
    /// Copies a solved cluster's contacts' forces and normals into string_pairs_.
    void keepForces(const Cluster& cl);

    std::vector<StringState>* strings_ = nullptr;  // this step's strings (couple, finish)
    ThreadPool* pool_ = nullptr;
    ChainTree tree_;
    bool tree_searched_ = false;  // the last findPairs ran the tree (its counters are this step's)
    // The search's segments: every live string's, string after string.
    std::vector<Vec3> grid_positions_;
    std::vector<Vec3> grid_travel_;      // per particle: x - x_prev after the strings' own solves
    std::vector<double> grid_thickness_; // per segment: its string's radius there
    double grid_rounding_ = 0.0;         // nodesSeparationNeeded's rounding margin (from the largest |x|_1)
    std::vector<CollisionSegment> grid_segments_;
    std::vector<SegmentPair> grid_pairs_;
    std::vector<PairString> pair_strings_;
    std::vector<std::uint8_t> self_free_;  // per entry of pair_strings_: selfPairFree held
    std::vector<std::uint8_t> pair_verdict_;  // per pair of grid_pairs_
    std::vector<StringPairContact> pair_contact_;
    std::vector<std::pair<PairKey, std::uint32_t>> contact_order_;  // key, index into pair_contact_
    // This step's contacts (global string indices, sorted by key) and the last step's
    // that pressed (warm start).
    std::vector<StringPairContact> string_pairs_, previous_pairs_;
    // Pairs that started a step deeper than kStringDeepStart (sorted) and have not come
    // apart since: no contacts until they have.
    std::vector<PairKey> deep_pairs_, deep_next_;
    std::vector<Cluster> clusters_;  // reused; the first `cluster_count_` of a step are in use
    std::size_t cluster_count_ = 0;
    std::vector<IslandMember*> coupled_;  // startCoupled's members
    std::vector<std::uint32_t> cluster_root_, cluster_local_, pair_root_;
    std::vector<std::size_t> cluster_first_, cluster_fill_, cluster_order_;
};

}  // namespace tearables::detail
