// The paper's broad phase for string-string collisions (Strings, Sec. 6), kept by the tests
// as a reference for the library's ChainTree (collision/grid.hpp): a uniform hash grid over
// the particles, and brute force. Particles are binned in cubic cells of size h; for every
// pair of particles A, B in neighbouring cells ("neighbouring": the paper's 7-cell stencil,
// own cell and 6 face neighbours, or the full 27-cell stencil), the segments at A are tested
// against those at B, with the library's narrow phase.
//
// Lemma (the cell size). Let P = a0 + s (a1 - a0) on segment 1 (length l1), Q = b0 +
// t (b1 - b0) on segment 2 (length l2). Pick endpoint a1 with probability s (else a0) and b1
// with probability t (else b0): E[a] = P, E[b] = Q and
//     E|a - b|^2 = |P - Q|^2 + s(1-s) l1^2 + t(1-t) l2^2 <= |P - Q|^2 + (l1^2 + l2^2) / 4,
// so for overlapping capsules (|P - Q| < r1 + r2 + margin) some endpoint pair is within
//     D12 = sqrt((l1^2 + l2^2) / 4 + (r1 + r2 + margin)^2)
//        <= D  = sqrt(l_max^2 / 2 + (2 r_max + margin)^2)      (requiredCellSize).
// Points at most h apart are in cells at most 1 apart per axis: with h >= D the 27-cell
// search is EXACT. The bound is tight for thin capsules: two perpendicular segments of
// length l crossing at their midpoints along the diagonals of a square of side l/sqrt(2)
// have every cross endpoint pair on a side of it, and with h < l/sqrt(2) the grid can be
// placed so that each side spans three cells.
//
// The paper's 7-cell claim (a pair of end particles in the 7 neighbouring cells for h >= l)
// fails for capsules at any cell size: two segments inside the cells (0,0,0) and (1,1,0),
// which share only an edge, can be arbitrarily close to it and to each other. For h = l = 1,
// r = 0.05 (axis distance 0.085 < 0.1):
//     (0.97, 0.97, 0.5) - (0.263, 0.263, 0.5)   and   (1.03, 1.03, 0.5) - (1.737, 1.737, 0.5).
// It fails even for zero-thickness segments that cross, in 3D (the paper's argument covers
// 2D only): with h = 1,
//     (0.02, -0.1, 0.5) - (0.02, 0.42, -0.02)   and   (0.1, 0.1, 1.02) - (-0.004, 0.1, 0.084)
// cross at (0.02, 0.1, 0.3) with endpoints in the cells (0,-1,0), (0,0,-1) and (0,0,1),
// (-1,0,0). NeighbourSearch::Seven finds the subset of the overlapping pairs that have an
// endpoint pair in the same or face-adjacent cells; TwentySeven is exact.
//
// Each particle pair is visited once (a half stencil); the 27-cell search skips particle
// pairs farther apart than D and tests a segment pair only at its first endpoint pair within
// D12 and the stencil, so the output has no duplicates. Cells map to the slots of a
// power-of-two table by a spatially coherent hash (SlotLayout); particles are counting-sorted
// by slot, stably: the output is deterministic. Rounding could only matter for a pair that
// realises D to within about 1e-16 |x| / h relative; positions beyond 2^30 cells are rejected.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "collision/grid.hpp"
#include "tearables/types.hpp"

namespace tearables::reference {

using detail::CollisionSegment;
using detail::SegmentInfo;
using detail::SegmentPair;

enum class NeighbourSearch {
    Seven,       ///< the paper's own cell + 6 face neighbours: fast, but misses pairs (see the file comment)
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
/// sqrt(max_segment_length^2 / 2 + (2 max_radius + margin)^2) (see the lemma in the file comment).
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

/// The hash grid and its working memory; reused, it does not allocate once warmed up.
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

}  // namespace tearables::reference
