// Broad phase for string-string collisions: a uniform hash grid over the particles of
// several chains that finds every pair of overlapping segment capsules (Strings, Sec. 6).
//
// Scheme (the paper's): particles, not segments, are binned into cubic cells of size h.
// For every pair of particles A, B in neighbouring cells, the segments adjacent to A are
// tested against the segments adjacent to B. A pair of segments is therefore found iff
// one endpoint of the first and one endpoint of the second lie in neighbouring cells.
// "Neighbouring" is either the 7-cell stencil of the paper (same cell or one of the 6
// face neighbours) or the full 27-cell stencil.
//
// What the cell size must be (proved here, verified by tests/collision/test_grid.cpp):
//
// Lemma. Let P = a0 + s (a1 - a0) lie on segment 1 (length l1) and Q = b0 + t (b1 - b0)
// on segment 2 (length l2). Pick the endpoint a1 with probability s (else a0) and,
// independently, b1 with probability t (else b0). Then E[a] = P, E[b] = Q, and
//     E|a - b|^2 = |P - Q|^2 + s(1-s) l1^2 + t(1-t) l2^2 <= |P - Q|^2 + (l1^2 + l2^2) / 4,
// so some endpoint pair is at most that far apart. If the capsules overlap, the closest
// points have |P - Q| < r1 + r2 + margin, hence some endpoint pair is within
//     D12 = sqrt((l1^2 + l2^2) / 4 + (r1 + r2 + margin)^2)
//        <= D  = sqrt(l_max^2 / 2 + (2 r_max + margin)^2)      (requiredCellSize).
// Two points whose coordinates differ by at most h lie in cells whose indices differ by
// at most 1 per axis. So with h >= D the 27-cell search is EXACT (finds every
// overlapping pair). The bound is tight for thin capsules: two perpendicular segments of
// length l crossing at their midpoints, along the diagonals of an axis-aligned square of
// side l/sqrt(2), have every cross endpoint pair on a side of that square; with
// h < l/sqrt(2) the grid can be placed so that each side spans three cells, and the
// 27-cell search misses them. (For r, margin -> 0, h >= l/sqrt(2) is necessary and
// sufficient; the paper's h >= l suffices for 27 cells iff 2 r_max + margin <= l/sqrt(2).)
//
// The paper's 7-cell claim ("if two segments intersect there is a pair of end particles in
// the 7 neighbouring cells, for voxel size >= l") does NOT hold for capsules, at any cell
// size: two segments lying entirely inside the cells (0,0,0) and (1,1,0), which share
// only an edge, can be arbitrarily close to that edge and to each other, yet all four of
// their endpoint pairs are in cells that differ in two coordinates. A segment fits inside
// a cell whenever l < h sqrt(3), i.e. always when h >= l; and for h < l/sqrt(2) even the
// 27-cell search fails. Counterexample for h = l = 1, r = 0.05 (axis distance 0.085 < 0.1):
//     (0.97, 0.97, 0.5) - (0.263, 0.263, 0.5)   and   (1.03, 1.03, 0.5) - (1.737, 1.737, 0.5).
// It fails even for zero-thickness segments that truly intersect, in 3D: with h = 1,
//     (0.02, -0.1, 0.5) - (0.02, 0.42, -0.02)   and   (0.1, 0.1, 1.02) - (-0.004, 0.1, 0.084)
// (lengths 0.735 and 0.942) cross at (0.02, 0.1, 0.3), but their endpoints are in the cells
// (0,-1,0), (0,0,-1) and (0,0,1), (-1,0,0), no two of them face-adjacent. (The paper's
// argument enumerates 2D cases only.) NeighbourSearch::Seven is kept as the paper's
// heuristic: it finds exactly the overlapping pairs that have an endpoint pair in the same
// or face-adjacent cells, a subset of the true pairs. On random rope piles it misses about
// 7% of the overlapping pairs, some of them deeply overlapping (see the tests and
// benchmarks). NeighbourSearch::TwentySeven is exact and is the one to use.
//
// Implementation: the 27-cell search also skips, before looking at segments, particle
// pairs farther apart than D (no segment pair needs them, by the lemma) and tests a
// segment pair only at its first endpoint pair (in a fixed order) that is within D12 and
// the stencil; the 7-cell search tests a segment pair at its first endpoint pair within
// the 7-cell stencil. So every segment pair is tested at most once and the output has no
// duplicates. Both visit every unordered particle pair once (a half stencil: the own cell
// and the 3 or 13 "forward" neighbours). Cells map to the slots of a power-of-two table
// (2 to 4 slots per binned particle) by a spatially coherent hash (raster order inside
// blocks of cells, a hashed offset per block; see SlotLayout in grid.cpp); particles are
// counting-sorted by slot, stably, so the traversal and the output are deterministic;
// the output is sorted by (first, second). All working memory lives in the SegmentGrid
// and only grows: repeated calls with the same or fewer particles and segments do not
// allocate (the output vector keeps its capacity too).
//
// Floating point: the search is exact in exact arithmetic. Rounding in floor(x / h) and in
// the distances could only matter for a pair that realises the bound D to within about
// 1e-16 |x| / h relative, so keep |x| / h well below 1e9 (positions beyond 2^30 cells are
// rejected).
#pragma once

#include <cmath>
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

enum class NeighbourSearch {
    Seven,       ///< the paper's own cell + 6 face neighbours: fast, but misses pairs (see above)
    TwentySeven  ///< own cell + all 26 neighbours: exact when cell_size >= requiredCellSize
};

/// Integer cell coordinates floor(x / h), computed as floor(x * inv_cell_size).
struct CellCoord {
    std::int32_t x = 0, y = 0, z = 0;
    friend bool operator==(const CellCoord& l, const CellCoord& r) { return l.x == r.x && l.y == r.y && l.z == r.z; }
    friend bool operator!=(const CellCoord& l, const CellCoord& r) { return !(l == r); }
};

/// The cell of a point, exactly as SegmentGrid bins particles (inv_cell_size = 1 / cell_size).
/// The point must be within 2^30 cells of the origin.
inline CellCoord cellOf(const Vec3& x, double inv_cell_size) {
    return {static_cast<std::int32_t>(std::floor(x.x() * inv_cell_size)),
            static_cast<std::int32_t>(std::floor(x.y() * inv_cell_size)),
            static_cast<std::int32_t>(std::floor(x.z() * inv_cell_size))};
}

/// The smallest cell size for which the 27-cell search is exact:
/// sqrt(max_segment_length^2 / 2 + (2 max_radius + margin)^2) (see the lemma above).
double requiredCellSize(double max_segment_length, double max_radius, double margin);

/// requiredCellSize of the current configuration: the longest current length and largest
/// radius over the segments that are not skipped (= margin when there are none). O(n), no
/// allocation; throws InvalidInput like SegmentGrid::findPairs (except for the cell size).
double requiredCellSize(const Vec3* positions, std::size_t particle_count,
                        const std::vector<CollisionSegment>& segments, double margin);

/// Counters of the last SegmentGrid::findPairs call (for benchmarks and tuning).
struct GridStats {
    std::size_t particles = 0;       ///< particles binned (those with a segment that is not skipped)
    std::size_t particle_pairs = 0;  ///< particle pairs visited in the stencil
    std::size_t narrow_tests = 0;    ///< closest-point computations (segment pairs tested)
};

/// The hash grid and its working memory; reuse one per world for allocation-free steps.
class SegmentGrid {
public:
    /// Finds every pair of segments whose capsules overlap: distance between the axes
    /// < r1 + r2 + margin. Pairs are never reported when a segment is `skip`, when the two
    /// segments share a particle (adjacent segments, whatever their chains), or when they
    /// belong to the same chain and |index_in_chain difference| <= skip_neighbours.
    /// `positions` holds particle_count particles; segments index into it. `out` is
    /// cleared and receives the pairs without duplicates, sorted by (first, second) when
    /// `sorted` (else in the search's own order, deterministic for the same input).
    ///
    /// Requires cell_size >= requiredCellSize(positions, particle_count, segments, margin)
    /// (for both searches; TwentySeven is then exact, Seven finds the subset described in
    /// the file comment). Throws InvalidInput ("cell_size", "margin", "segments[i].a",
    /// "segments[i].b", "segments[i].radius", "positions") on a smaller or non-finite cell
    /// size, a negative margin, a particle index out of range or a == b, a negative or
    /// non-finite radius, a non-finite position or one beyond 2^30 cells.
    void findPairs(const Vec3* positions, std::size_t particle_count, const std::vector<CollisionSegment>& segments,
                   double cell_size, double margin, NeighbourSearch search, std::vector<SegmentPair>& out,
                   std::uint32_t skip_neighbours = 1, bool sorted = true);

    /// Counters of the last findPairs call.
    const GridStats& lastStats() const { return stats_; }

    /// Bytes of working memory currently reserved (stays constant once warmed up).
    std::size_t reservedBytes() const;

    struct SegmentInfo {  // implementation detail: per-segment data of the current call
        Vec3 mid = Vec3::Zero();
        double half_length = 0.0;
        double length2 = 0.0;
    };

private:
    std::vector<SegmentInfo> seg_info_;      // per segment
    std::vector<std::uint32_t> inc_start_;   // per particle + 1: CSR of segments at a particle
    std::vector<std::uint32_t> inc_list_;    // the incident segments, in segment order
    std::vector<CellCoord> cell_;            // per particle
    std::vector<std::uint32_t> binned_;      // particles with at least one segment, ascending
    std::vector<std::uint32_t> slot_;        // hash slot per binned particle
    std::vector<std::uint32_t> entry_;       // per binned particle: its index in the sorted order
    std::vector<std::uint32_t> slot_start_;  // per slot + 1: counting-sort offsets
    std::vector<std::uint32_t> sorted_id_;   // binned particles, by slot then index
    std::vector<CellCoord> sorted_cell_;     // their cells, in the same order
    std::vector<Vec3> sorted_x_;             // their positions, in the same order
    GridStats stats_;
};

/// All overlapping pairs by testing every pair of segments (O(n^2)): same filters, same
/// narrow phase and same output as SegmentGrid::findPairs with an exact search. For tests
/// and benchmarks. Throws InvalidInput like findPairs (except for the cell size).
std::vector<SegmentPair> bruteForcePairs(const Vec3* positions, std::size_t particle_count,
                                         const std::vector<CollisionSegment>& segments, double margin,
                                         std::uint32_t skip_neighbours = 1);

/// The same search as SegmentGrid::findPairs (every pair of overlapping capsules, the
/// same exclusions, the same narrow phase, so the same pairs with the same closest points),
/// through a bounding-box tree per chain instead of a grid. The grid's cells must fit the
/// largest capsule, so one fast segment (a swept capsule grown by its travel: the tip of a
/// swinging rope) makes every cell large and every particle meet hundreds of others; the
/// tree's boxes follow each segment's own size. Chains are the runs of consecutive
/// segments with the same `chain` value in the list (strings listed one after another).
/// Per chain: a tree over its segment ranges built bottom-up in O(n) (leaves of up to
/// kLeaf segments), self pairs by descending the tree (siblings of a curved chain touch
/// only near their common particle), chains against each other by sweeping their root
/// boxes along x and descending both trees where the roots overlap. Output in the order of
/// the traversal (deterministic); no allocation once the buffers have grown.
class ThreadPool;

class ChainTree {
public:
    /// With a `pool`, the segments' boxes and each chain's tree and self pairs are done on
    /// it (chains are independent; each chain's pairs are collected in a buffer of its own
    /// and appended in chain order, so the output is the same for any thread count).
    /// With a `keep` filter, only the pairs for which keep(context, pair) is true are
    /// output (it is called as the pairs are found, from the pool's threads: it must only
    /// read), so that a caller dropping most pairs never stores them.
    /// With a `reject` test as well, a candidate pair (segments i < j) for which
    /// reject(context, i, j) is true is dropped before its closest points are computed (the
    /// caller's proof that `keep` would drop it). With a `sweep` (travel per particle,
    /// thickness per segment, a NodeSeparation test), every node also bounds its segments'
    /// axes, travel, directions and thickness, and a pair of nodes whose boxes overlap is
    /// skipped whole when the sweep's test says so (for a swinging rope: segments whose
    /// swept capsules overlap but whose relative travel is small beside their separation).
    /// With `self_free` (one flag per chain), the chains flagged are not searched for self
    /// pairs (the caller's proof that `keep` would drop every one); their trees are still
    /// built for the pairs with other chains.
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
    std::vector<SegmentGrid::SegmentInfo> info_;
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
