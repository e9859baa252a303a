// Broad phase for string-string collisions (Strings, Sec. 6): every pair of segment
// capsules of several chains closer than r1 + r2 + margin, through a bounding-box tree per
// chain (ChainTree), and the narrow phase it shares with the tests' reference searches
// (tests/collision/reference_grid.hpp: the paper's hash grid and brute force).
//
// The paper bins particles in a uniform grid; its cells must fit the largest capsule, so
// one fast segment (a swept capsule grown by its travel) makes every cell large. A tree's
// boxes follow each segment's own size and find the same pairs.
#pragma once

#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

#include "tearables/types.hpp"

namespace tearables::detail {

/// A segment of some chain: a capsule around the axis from particle a to particle b.
struct CollisionSegment {
    std::uint32_t a = 0;               ///< first particle (global index into the positions)
    std::uint32_t b = 0;               ///< second particle, != a
    std::uint32_t chain = 0;           ///< owner (string / piece) id
    std::uint32_t index_in_chain = 0;  ///< position along the owner, for the neighbour skip
    double radius = 0.0;               ///< capsule radius, >= 0
    bool skip = false;                 ///< broken (torn) or otherwise excluded: never reported
};

/// Two overlapping capsules: segments `first` < `second` (indices into the segment list).
struct SegmentPair {
    std::uint32_t first = 0;
    std::uint32_t second = 0;
    double s = 0.0;               ///< closest point on first: x[a] + s (x[b] - x[a]) of segments[first]
    double t = 0.0;               ///< closest point on second: x[a] + t (x[b] - x[a]) of segments[second]
    Vec3 normal = Vec3::UnitX();  ///< unit, from the second's closest point to the first's
    double distance = 0.0;        ///< between the axes (< r1 + r2 + margin)
};

/// A segment's midpoint and length, as the narrow phase's bounding spheres use them.
struct SegmentInfo {
    Vec3 mid = Vec3::Zero();
    double half_length = 0.0;
    double length2 = 0.0;  ///< squared length
};

/// Relative slack on squared distances compared against bounds, so that rounding in the
/// computed lengths and distances never rejects a pair the bound guarantees (a few ulps
/// are needed; 1e-9 is ample for |x| / cell size < 1e6).
constexpr double kPairSlack = 1.0 + 1e-9;

/// Whether a pair is never reported: the segments share a particle, or they belong to the
/// same chain and |index_in_chain difference| <= skip_neighbours.
bool excludedPair(const CollisionSegment& si, const CollisionSegment& sj, std::uint32_t skip_neighbours);

/// The narrow phase of every search, for segments i < j: a bounding-sphere rejection, then
/// the closest points of the axes. Appends the pair to `out` when the capsules overlap
/// (distance < r_i + r_j + margin); returns whether the closest points were computed.
bool narrowPhase(const Vec3* x, const std::vector<CollisionSegment>& segs, const SegmentInfo* info, double margin,
                 std::uint32_t i, std::uint32_t j, std::vector<SegmentPair>& out);

class ThreadPool;

/// Every pair of overlapping capsules (distance between the axes < r1 + r2 + margin),
/// except the excludedPair ones and the skipped segments. Chains are the runs of consecutive
/// segments with the same `chain` value in the list (strings listed one after another).
/// Per chain: a tree over its segment ranges built bottom-up in O(n) (leaves of up to
/// kLeaf segments), self pairs by descending the tree (siblings of a curved chain touch
/// only near their common particle), chains against each other by sweeping their root
/// boxes along the axis on which their centres spread most and descending both trees where
/// the roots overlap. Output in the order of the traversal (deterministic); no allocation
/// once the buffers have grown.
class ChainTree {
public:
    using Filter = bool (*)(const void* context, const SegmentPair& pair);
    using Reject = bool (*)(const void* context, std::uint32_t i, std::uint32_t j);

    /// What a node of the tree holds, for a caller that drops whole node pairs (Sweep):
    /// bounds over the node's segments of their end particles' positions (the capsules'
    /// axes, not grown by any radius), of those particles' `travel` vectors, and the
    /// largest `thickness` of its segments (skipped segments included: a bound).
    struct NodeBounds {
        Vec3 lo = Vec3::Zero(), hi = Vec3::Zero();                ///< axes' end positions
        Vec3 travel_lo = Vec3::Zero(), travel_hi = Vec3::Zero();  ///< end particles' travel
        Vec3 tangent_lo = Vec3::Zero(), tangent_hi = Vec3::Zero();///< axes' unit directions
        double thickness = 0.0;                                   ///< largest per-segment value
    };
    /// separation(context, a, b): a distance such that, when every point of the axes of
    /// node a's segments and every point of node b's are further apart than it along one
    /// unit direction, the caller's `reject`/`keep` would drop every pair of them (its
    /// proof). The tree then skips the node pair whole: the output is exactly what it is
    /// without it. It tries the coordinate axis that separates the nodes' position boxes
    /// most and, along a chain that turns by less than a right angle (see cross), the
    /// chain's own direction: a rope swinging as a whole, whose neighbouring nodes' boxes
    /// overlap but whose segments further apart along it than a few thicknesses are also
    /// that far apart in space. One call per node pair.
    using NodeSeparation = double (*)(const void* context, const NodeBounds& a, const NodeBounds& b);
    struct Sweep {
        const Vec3* travel = nullptr;     ///< per particle (indexed like positions)
        const double* thickness = nullptr;///< per segment
        NodeSeparation separation = nullptr;
    };

    /// The overlapping pairs of `segments` into `out`. Optional:
    /// - `pool`: boxes, trees and self pairs chain by chain on it, each chain's pairs in a
    ///   buffer of its own, appended in chain order (the same output for any thread count);
    /// - `keep`: only the pairs with keep(context, pair) are output, called as they are found,
    ///   from the pool's threads (it must only read), so dropped pairs are never stored;
    /// - `reject`: a candidate i < j with reject(context, i, j) is dropped before its closest
    ///   points (the caller's proof that `keep` would drop it);
    /// - `sweep`: nodes also bound their segments' axes, travel, directions and thickness,
    ///   and a node pair is skipped whole where sweep->separation says `keep` drops it all
    ///   (a swinging rope: swept capsules overlap, relative travel is small);
    /// - `self_free`: per chain, 1 where `keep` would drop every self pair (its tree is
    ///   still built for the pairs with other chains).
    void findPairs(const Vec3* positions, const std::vector<CollisionSegment>& segments, double margin,
                   std::vector<SegmentPair>& out, std::uint32_t skip_neighbours = 1, ThreadPool* pool = nullptr,
                   Filter keep = nullptr, const void* context = nullptr, Reject reject = nullptr,
                   const Sweep* sweep = nullptr, const std::uint8_t* self_free = nullptr);

    /// Node pairs the last findPairs skipped whole through its Sweep (for tests, benchmarks).
    std::size_t lastNodeRejects() const;

private:
    struct Node {
        Vec3 lo = Vec3::Zero(), hi = Vec3::Zero();  // bounds of the capsules (grown by half the margin)
        std::uint32_t first = 0;     // segment range [first, first + count)
        std::uint32_t count = 0;
        std::uint32_t left = 0, right = 0;  // children (leaves: 0)
    };
    std::uint32_t build(std::uint32_t first, std::uint32_t count, std::uint32_t& next);
    /// Node `index` over segments [first, first + count) with children left and right.
    void join(std::uint32_t index, std::uint32_t first, std::uint32_t count, std::uint32_t left, std::uint32_t right);
    /// Chain c's tree and (unless `self_free`) self pairs, on two threads of `pool`.
    void splitChain(std::size_t c, ThreadPool& pool, bool self_free);
    /// `along`: a unit direction along which every segment of the node (and so of its
    /// children) points forward, or null (see cross).
    void self(std::uint32_t node, std::vector<SegmentPair>& out, std::size_t& rejects, const Vec3* along = nullptr) const;
    /// `along` (null, or as for self): a's segments come before b's in one chain, and every
    /// segment from a's first to b's last points forward along it.
    void cross(std::uint32_t a, std::uint32_t b, std::vector<SegmentPair>& out, std::size_t& rejects,
               const Vec3* along = nullptr) const;
    /// A unit direction along which every segment of `node` points forward, from its
    /// tangent bounds, into `along`; false where none is found (the chain turns too much).
    bool forwardDirection(std::uint32_t node, Vec3& along) const;
    /// Whether the nodes carry NodeBounds (findPairs was given a Sweep).
    bool bounded() const { return sweep_.travel != nullptr; }
    void test(std::uint32_t i, std::uint32_t j, std::vector<SegmentPair>& out) const;

    std::vector<Node> nodes_;
    std::vector<NodeBounds> bounds_;  // per node, with a Sweep only
    std::vector<Vec3> seg_lo_, seg_hi_;
    std::vector<SegmentInfo> info_;
    std::vector<std::uint32_t> roots_, order_;
    std::vector<std::uint32_t> chain_first_, chain_count_, chain_node_;  // per chain: segments, first node
    std::vector<std::vector<SegmentPair>> chain_out_;                    // per chain: its self pairs
    std::vector<SegmentPair> split_out_[3];                              // splitChain's parts
    std::vector<std::pair<std::uint32_t, std::uint32_t>> root_pairs_;   // roots the sweep pairs up
    std::vector<std::vector<SegmentPair>> root_out_;                     // per root pair: its pairs
    const Vec3* x_ = nullptr;
    const std::vector<CollisionSegment>* segs_ = nullptr;
    double margin_ = 0.0;
    Filter keep_ = nullptr;
    Reject reject_ = nullptr;
    Sweep sweep_;
    const void* keep_context_ = nullptr;
    std::vector<std::size_t> chain_rejects_, root_rejects_;  // node rejects per chain / root pair
    std::uint32_t skip_ = 1;
};

}  // namespace tearables::detail
