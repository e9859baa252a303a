// Uniform hash grid broad phase for segment capsules; see grid.hpp for the scheme and the
// proof of the cell-size condition.
#include "collision/grid.hpp"

#include <algorithm>
#include <limits>
#include <string>

#include "collision/capsule.hpp"
#include "base/thread_pool.hpp"

namespace tearables::detail {

namespace {

using SegmentInfo = SegmentGrid::SegmentInfo;

// Relative slack on squared distances compared against the bounds of grid.hpp, so that
// rounding in the computed lengths and distances never turns a pair the lemma guarantees
// into one that is rejected (a few ulps relative; 1e-9 is ample for |x| / h < 1e6).
constexpr double kSlack = 1.0 + 1e-9;
// Cell coordinates are kept within +-2^30 so that neighbour offsets never overflow int32.
constexpr double kMaxCell = 1073741824.0;

std::string segField(std::size_t i, const char* member) { return "segments[" + std::to_string(i) + "]." + member; }

struct Validated {
    double max_length = 0.0;
    double max_length2 = 0.0;  // max of the squared lengths as stored in SegmentInfo
    double max_radius = 0.0;
};

// Checks the segments and positions; fills info[i] (when `info` is given: one entry per
// segment) for the segments that are not skipped.
Validated validate(const Vec3* x, std::size_t particle_count, const std::vector<CollisionSegment>& segs, double margin,
                   SegmentInfo* info) {
    if (!(margin >= 0.0) || !std::isfinite(margin)) throw InvalidInput("margin", "must be finite and >= 0");
    if (segs.size() >= std::numeric_limits<std::uint32_t>::max())
        throw InvalidInput("segments", "too many segments (must fit in uint32)");
    Validated v;
    for (std::size_t i = 0; i < segs.size(); ++i) {
        const CollisionSegment& sg = segs[i];
        if (sg.skip) continue;
        if (sg.a >= particle_count) throw InvalidInput(segField(i, "a"), "particle index out of range");
        if (sg.b >= particle_count) throw InvalidInput(segField(i, "b"), "particle index out of range");
        if (sg.a == sg.b) throw InvalidInput(segField(i, "b"), "must differ from a");
        if (!(sg.radius >= 0.0) || !std::isfinite(sg.radius))
            throw InvalidInput(segField(i, "radius"), "must be finite and >= 0");
        const Vec3& xa = x[sg.a];
        const Vec3& xb = x[sg.b];
        if (!xa.allFinite() || !xb.allFinite()) throw InvalidInput("positions", "must be finite");
        const double length2 = (xb - xa).squaredNorm();
        const double half_length = 0.5 * std::sqrt(length2);
        if (info) info[i] = {0.5 * (xa + xb), half_length, length2};
        v.max_length = std::max(v.max_length, 2.0 * half_length);
        v.max_length2 = std::max(v.max_length2, length2);
        v.max_radius = std::max(v.max_radius, sg.radius);
    }
    return v;
}

// Pairs that are never reported: sharing a particle, or too close along the same chain.
bool excluded(const CollisionSegment& si, const CollisionSegment& sj, std::uint32_t skip_neighbours) {
    if (si.a == sj.a || si.a == sj.b || si.b == sj.a || si.b == sj.b) return true;
    if (si.chain != sj.chain) return false;
    const std::uint32_t d = si.index_in_chain > sj.index_in_chain ? si.index_in_chain - sj.index_in_chain
                                                                  : sj.index_in_chain - si.index_in_chain;
    return d <= skip_neighbours;
}

// The narrow phase shared by every search (i < j): a bounding-sphere rejection, then the
// closest points of the axes. Appends the pair to `out` when the capsules overlap.
// Returns whether the closest points were computed.
bool narrowPhase(const Vec3* x, const std::vector<CollisionSegment>& segs, const SegmentInfo* info, double margin,
                 std::uint32_t i, std::uint32_t j, std::vector<SegmentPair>& out) {
    const CollisionSegment& si = segs[i];
    const CollisionSegment& sj = segs[j];
    const double reach = si.radius + sj.radius + margin;
    // The capsules fit in spheres about the midpoints of radius half_length + radius.
    const double sphere = info[i].half_length + info[j].half_length + reach;
    if ((info[i].mid - info[j].mid).squaredNorm() > sphere * sphere * kSlack) return false;
    const SegmentClosest c = closestPointsOfSegments(x[si.a], x[si.b], x[sj.a], x[sj.b]);
    if (!(c.distance < reach)) return true;
    SegmentPair pr;
    pr.first = i;
    pr.second = j;
    pr.s = c.s;
    pr.t = c.t;
    pr.distance = c.distance;
    if (c.distance > 0.0) {
        pr.normal = (c.p - c.q) / c.distance;
    } else {
        // The axes touch: any direction is a normal; take one perpendicular to both axes
        // when they are not parallel, else one perpendicular to an axis, else x.
        const Vec3 d1 = x[si.b] - x[si.a];
        const Vec3 d2 = x[sj.b] - x[sj.a];
        Vec3 n = d1.cross(d2);
        if (!(n.squaredNorm() > 1e-24 * d1.squaredNorm() * d2.squaredNorm())) {
            const Vec3 d = d1.squaredNorm() >= d2.squaredNorm() ? d1 : d2;
            n = d.squaredNorm() > 0.0 ? d.unitOrthogonal() : Vec3::UnitX();
        }
        pr.normal = n.normalized();
    }
    out.push_back(pr);
    return true;
}

std::uint32_t nextPow2(std::size_t n) {
    std::uint32_t p = 16;
    while (p < n) p <<= 1;
    return p;
}

std::uint64_t mix(std::uint64_t h) {
    h ^= h >> 29;
    h *= 0xBF58476D1CE4E5B9ull;
    h ^= h >> 32;
    return h;
}

// Maps cells to the slots of a power-of-two table, spatially coherently: space is tiled
// into blocks of 2^bx x 2^by x 2^bz cells (bx + by + bz <= log2(table)); inside a block
// the slot is the cell's raster index (x fastest), plus a per-block hash offset, modulo
// the table. So +x neighbours are in the next slot and a traversal in slot order sweeps
// space in raster order (its neighbour look-ups stream through memory), while cells of
// different blocks still spread over the table like a hash. When the particles' bounding
// box fits in one block (extents <= 2^b per axis) no two occupied cells share a slot.
struct SlotLayout {
    CellCoord origin;  // the bounding box's lowest cell
    int bx = 0, by = 0, bz = 0;
    std::uint32_t mask = 0;  // table size - 1

    void choose(const CellCoord& lo, const CellCoord& hi, std::uint32_t table) {
        origin = lo;
        mask = table - 1;
        int budget = 0;
        while ((1u << budget) < table) ++budget;
        auto bitsFor = [](std::int64_t extent) {
            int b = 0;
            while ((std::int64_t{1} << b) < extent) ++b;
            return b;
        };
        bx = bitsFor(std::int64_t{hi.x} - lo.x + 1);
        by = bitsFor(std::int64_t{hi.y} - lo.y + 1);
        bz = bitsFor(std::int64_t{hi.z} - lo.z + 1);
        while (bx + by + bz > budget) {  // shrink the largest (ties: z, then y): near-cubic blocks
            if (bz >= by && bz >= bx)
                --bz;
            else if (by >= bx)
                --by;
            else
                --bx;
        }
    }

    std::uint32_t slot(const CellCoord& c) const {
        // Offsets from the origin in wrapping unsigned arithmetic (cells below the origin,
        // looked up as neighbours, just land in some other block).
        const std::uint32_t ux = static_cast<std::uint32_t>(c.x) - static_cast<std::uint32_t>(origin.x);
        const std::uint32_t uy = static_cast<std::uint32_t>(c.y) - static_cast<std::uint32_t>(origin.y);
        const std::uint32_t uz = static_cast<std::uint32_t>(c.z) - static_cast<std::uint32_t>(origin.z);
        const std::uint32_t local =
            (ux & ((1u << bx) - 1)) | ((uy & ((1u << by) - 1)) << bx) | ((uz & ((1u << bz) - 1)) << (bx + by));
        const std::uint64_t block = mix((static_cast<std::uint64_t>(ux >> bx) * 0x9E3779B97F4A7C15ull) ^
                                        (static_cast<std::uint64_t>(uy >> by) * 0xC2B2AE3D27D4EB4Full) ^
                                        (static_cast<std::uint64_t>(uz >> bz) * 0x165667B19E3779F9ull));
        return (local + static_cast<std::uint32_t>(block)) & mask;
    }
};

inline int absDiff(std::int32_t a, std::int32_t b) { return a > b ? a - b : b - a; }

// Cells within the 7-cell stencil (same or face-adjacent) / the 27-cell stencil.
inline bool sevenAdjacent(const CellCoord& a, const CellCoord& b) {
    return absDiff(a.x, b.x) + absDiff(a.y, b.y) + absDiff(a.z, b.z) <= 1;
}
inline bool twentySevenAdjacent(const CellCoord& a, const CellCoord& b) {
    return absDiff(a.x, b.x) <= 1 && absDiff(a.y, b.y) <= 1 && absDiff(a.z, b.z) <= 1;
}

// The "forward" half of each stencil: every unordered pair of distinct neighbouring cells
// has exactly one of its two offsets here.
constexpr int kForward7[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
constexpr int kForward27[13][3] = {{1, -1, -1}, {1, -1, 0}, {1, -1, 1}, {1, 0, -1}, {1, 0, 0}, {1, 0, 1}, {1, 1, -1},
                                   {1, 1, 0},   {1, 1, 1},  {0, 1, -1}, {0, 1, 0},  {0, 1, 1}, {0, 0, 1}};

// Visits the segment pairs of one particle pair (A, B).
template <bool kSeven>
struct PairVisitor {
    const Vec3* x;
    const std::vector<CollisionSegment>& segs;
    const SegmentInfo* info;
    const std::uint32_t* inc_start;
    const std::uint32_t* inc_list;
    const CellCoord* cell;  // per particle
    const Vec3* sorted_x;   // per sorted entry (slot order)
    const std::uint32_t* sorted_id;
    double margin;
    double dmax2;  // squared bound D^2 (with slack), 27 only
    std::uint32_t skip_neighbours;
    std::vector<SegmentPair>& out;
    GridStats& stats;

    // Whether an endpoint pair (u of segment i, v of segment j) may carry the test of the
    // segment pair: in the stencil and, for 27 cells, within D12 (the lemma's bound).
    bool eligible(std::uint32_t u, std::uint32_t v, double d12sq) const {
        if constexpr (kSeven) {
            (void)d12sq;
            return sevenAdjacent(cell[u], cell[v]);
        } else {
            return twentySevenAdjacent(cell[u], cell[v]) && (x[u] - x[v]).squaredNorm() <= d12sq;
        }
    }

    // Visits the particle pair of the sorted entries ea, eb.
    void operator()(std::uint32_t ea, std::uint32_t eb) {
        ++stats.particle_pairs;
        if constexpr (!kSeven) {
            // No segment pair can be tested at a particle pair farther apart than D.
            if ((sorted_x[ea] - sorted_x[eb]).squaredNorm() > dmax2) return;
        }
        const std::uint32_t pa = sorted_id[ea];
        const std::uint32_t pb = sorted_id[eb];
        for (std::uint32_t ka = inc_start[pa]; ka < inc_start[pa + 1]; ++ka) {
            const std::uint32_t sa = inc_list[ka];
            for (std::uint32_t kb = inc_start[pb]; kb < inc_start[pb + 1]; ++kb) {
                const std::uint32_t sb = inc_list[kb];
                if (sa == sb) continue;
                const bool a_first = sa < sb;
                const std::uint32_t i = a_first ? sa : sb;
                const std::uint32_t j = a_first ? sb : sa;
                const CollisionSegment& si = segs[i];
                const CollisionSegment& sj = segs[j];
                if (excluded(si, sj, skip_neighbours)) continue;
                // The endpoint pair of this visit: u on segment i, v on segment j.
                const std::uint32_t u = a_first ? pa : pb;
                const std::uint32_t v = a_first ? pb : pa;
                const std::uint32_t ends_i[2] = {si.a, si.b};
                const std::uint32_t ends_j[2] = {sj.a, sj.b};
                const int here = 2 * (si.a == u ? 0 : 1) + (sj.a == v ? 0 : 1);
                double d12sq = 0.0;
                if constexpr (!kSeven) {
                    const double reach = si.radius + sj.radius + margin;
                    d12sq = (0.25 * (info[i].length2 + info[j].length2) + reach * reach) * kSlack;
                    if (!eligible(u, v, d12sq)) continue;
                }
                // Test the segment pair only at its first eligible endpoint pair, in the
                // order (a_i,a_j), (a_i,b_j), (b_i,a_j), (b_i,b_j): each is visited once.
                bool earlier = false;
                for (int k = 0; k < here && !earlier; ++k) earlier = eligible(ends_i[k >> 1], ends_j[k & 1], d12sq);
                if (earlier) continue;
                if (narrowPhase(x, segs, info, margin, i, j, out)) ++stats.narrow_tests;
            }
        }
    }
};

}  // namespace

double requiredCellSize(double max_segment_length, double max_radius, double margin) {
    const double reach = 2.0 * max_radius + margin;
    return std::sqrt(0.5 * max_segment_length * max_segment_length + reach * reach);
}

double requiredCellSize(const Vec3* positions, std::size_t particle_count,
                        const std::vector<CollisionSegment>& segments, double margin) {
    const Validated v = validate(positions, particle_count, segments, margin, nullptr);
    return requiredCellSize(v.max_length, v.max_radius, margin);
}

void SegmentGrid::findPairs(const Vec3* positions, std::size_t particle_count,
                            const std::vector<CollisionSegment>& segments, double cell_size, double margin,
                            NeighbourSearch search, std::vector<SegmentPair>& out, std::uint32_t skip_neighbours, bool sorted) {
    out.clear();
    stats_ = GridStats{};
    if (!(cell_size > 0.0) || !std::isfinite(cell_size)) throw InvalidInput("cell_size", "must be finite and > 0");
    if (particle_count >= std::numeric_limits<std::uint32_t>::max())
        throw InvalidInput("positions", "too many particles (must fit in uint32)");
    seg_info_.resize(segments.size());
    const Validated v = validate(positions, particle_count, segments, margin, seg_info_.data());
    const double required = requiredCellSize(v.max_length, v.max_radius, margin);
    if (cell_size < required)
        throw InvalidInput("cell_size", "must be >= sqrt(l_max^2/2 + (2 r_max + margin)^2) = " +
                                            std::to_string(required) + " (longest segment, largest radius)");
    const Vec3* x = positions;

    // Segments at each particle (CSR, in segment order); the particles that have any.
    inc_start_.assign(particle_count + 1, 0);
    for (const CollisionSegment& sg : segments) {
        if (sg.skip) continue;
        ++inc_start_[sg.a + 1];
        ++inc_start_[sg.b + 1];
    }
    binned_.clear();
    for (std::size_t p = 0; p < particle_count; ++p) {
        if (inc_start_[p + 1] != 0) binned_.push_back(static_cast<std::uint32_t>(p));
        inc_start_[p + 1] += inc_start_[p];
    }
    inc_list_.resize(inc_start_[particle_count]);
    for (std::size_t i = 0; i < segments.size(); ++i) {
        const CollisionSegment& sg = segments[i];
        if (sg.skip) continue;
        // inc_start_[p] is used as the fill cursor and restored below.
        inc_list_[inc_start_[sg.a]++] = static_cast<std::uint32_t>(i);
        inc_list_[inc_start_[sg.b]++] = static_cast<std::uint32_t>(i);
    }
    for (std::size_t p = particle_count; p > 0; --p) inc_start_[p] = inc_start_[p - 1];
    inc_start_[0] = 0;
    stats_.particles = binned_.size();

    // Cells, slots and the counting sort of the binned particles by slot.
    const double inv_h = 1.0 / cell_size;
    cell_.resize(particle_count);
    CellCoord lo{}, hi{};
    for (std::size_t k = 0; k < binned_.size(); ++k) {
        const std::uint32_t p = binned_[k];
        if (!((x[p] * inv_h).cwiseAbs().maxCoeff() < kMaxCell))
            throw InvalidInput("positions", "more than 2^30 cells from the origin");
        const CellCoord c = cellOf(x[p], inv_h);
        cell_[p] = c;
        if (k == 0) lo = hi = c;
        lo = {std::min(lo.x, c.x), std::min(lo.y, c.y), std::min(lo.z, c.z)};
        hi = {std::max(hi.x, c.x), std::max(hi.y, c.y), std::max(hi.z, c.z)};
    }
    const std::uint32_t table = nextPow2(2 * binned_.size());
    SlotLayout layout;
    layout.choose(lo, hi, table);
    slot_.resize(binned_.size());
    slot_start_.assign(static_cast<std::size_t>(table) + 1, 0);
    for (std::size_t k = 0; k < binned_.size(); ++k) {
        slot_[k] = layout.slot(cell_[binned_[k]]);
        ++slot_start_[slot_[k] + 1];
    }
    for (std::uint32_t s = 0; s < table; ++s) slot_start_[s + 1] += slot_start_[s];
    // Scatter in particle order (stable): within a slot, particles stay ascending. The
    // sorted copies of ids, cells and positions make the neighbour scans contiguous.
    entry_.resize(binned_.size());
    sorted_id_.resize(binned_.size());
    sorted_cell_.resize(binned_.size());
    sorted_x_.resize(binned_.size());
    for (std::size_t k = 0; k < binned_.size(); ++k) {
        const std::uint32_t p = binned_[k];
        const std::uint32_t e = slot_start_[slot_[k]]++;
        entry_[k] = e;
        sorted_id_[e] = p;
        sorted_cell_[e] = cell_[p];
        sorted_x_[e] = x[p];
    }
    for (std::uint32_t s = table; s > 0; --s) slot_start_[s] = slot_start_[s - 1];
    slot_start_[0] = 0;

    // Every unordered pair of particles in neighbouring cells, once: from each particle A
    // (in particle order, which follows the chains, so that consecutive particles share
    // their neighbour cells and segment data in the caches), the later entries of its own
    // cell in the slot (higher particle indices) and the entries of its forward neighbour
    // cells.
    auto traverse = [&](auto& visit, const int(*forward)[3], int n_forward) {
        const CellCoord* sc = sorted_cell_.data();
        const std::uint32_t mx = (1u << layout.bx) - 1, my = (1u << layout.by) - 1, mz = (1u << layout.bz) - 1;
        std::uint32_t step[13];  // slot step to each forward neighbour inside a block
        for (int o = 0; o < n_forward; ++o)
            step[o] = static_cast<std::uint32_t>(forward[o][0]) +
                      (static_cast<std::uint32_t>(forward[o][1]) << layout.bx) +
                      (static_cast<std::uint32_t>(forward[o][2]) << (layout.bx + layout.by));
        std::uint32_t nb_begin[13], nb_end[13];
        CellCoord nb_cell[13];
        CellCoord cached{};
        bool have_cached = false;
        for (std::size_t k = 0; k < binned_.size(); ++k) {
            const std::uint32_t s = slot_[k];
            const std::uint32_t ea = entry_[k];
            const CellCoord ca = sc[ea];
            for (std::uint32_t eb = ea + 1, end = slot_start_[s + 1]; eb < end; ++eb)
                if (sc[eb] == ca) visit(ea, eb);
            // The forward neighbours' slot ranges, looked up once per cell.
            if (!have_cached || cached != ca) {
                cached = ca;
                have_cached = true;
                const std::uint32_t lx =
                    (static_cast<std::uint32_t>(ca.x) - static_cast<std::uint32_t>(layout.origin.x)) & mx;
                const std::uint32_t ly =
                    (static_cast<std::uint32_t>(ca.y) - static_cast<std::uint32_t>(layout.origin.y)) & my;
                const std::uint32_t lz =
                    (static_cast<std::uint32_t>(ca.z) - static_cast<std::uint32_t>(layout.origin.z)) & mz;
                const bool inner = lx >= 1 && lx < mx && ly >= 1 && ly < my && lz >= 1 && lz < mz;
                for (int o = 0; o < n_forward; ++o) {
                    nb_cell[o] = {ca.x + forward[o][0], ca.y + forward[o][1], ca.z + forward[o][2]};
                    const std::uint32_t ns = inner ? (s + step[o]) & layout.mask : layout.slot(nb_cell[o]);
                    nb_begin[o] = slot_start_[ns];
                    nb_end[o] = slot_start_[ns + 1];
                }
            }
            for (int o = 0; o < n_forward; ++o)
                for (std::uint32_t eb = nb_begin[o]; eb < nb_end[o]; ++eb)
                    if (sc[eb] == nb_cell[o]) visit(ea, eb);
        }
    };

    // D^2 in the same form as each pair's D12^2 (so that D12^2 <= D^2 holds after rounding
    // too, and the early rejection never drops a pair that the canonical test relies on).
    const double max_reach = (v.max_radius + v.max_radius) + margin;
    const double dmax2 = (0.25 * (v.max_length2 + v.max_length2) + max_reach * max_reach) * kSlack;
    if (search == NeighbourSearch::Seven) {
        PairVisitor<true> visit{x,
                                segments,
                                seg_info_.data(),
                                inc_start_.data(),
                                inc_list_.data(),
                                cell_.data(),
                                sorted_x_.data(),
                                sorted_id_.data(),
                                margin,
                                0.0,
                                skip_neighbours,
                                out,
                                stats_};
        traverse(visit, kForward7, 3);
    } else {
        PairVisitor<false> visit{x,
                                 segments,
                                 seg_info_.data(),
                                 inc_start_.data(),
                                 inc_list_.data(),
                                 cell_.data(),
                                 sorted_x_.data(),
                                 sorted_id_.data(),
                                 margin,
                                 dmax2,
                                 skip_neighbours,
                                 out,
                                 stats_};
        traverse(visit, kForward27, 13);
    }
    if (sorted)
        std::sort(out.begin(), out.end(), [](const SegmentPair& l, const SegmentPair& r) {
            return l.first != r.first ? l.first < r.first : l.second < r.second;
        });
}

std::size_t SegmentGrid::reservedBytes() const {
    return seg_info_.capacity() * sizeof(SegmentInfo) +
           (inc_start_.capacity() + inc_list_.capacity() + binned_.capacity() + slot_.capacity() + entry_.capacity() +
            slot_start_.capacity() + sorted_id_.capacity()) *
               sizeof(std::uint32_t) +
           (cell_.capacity() + sorted_cell_.capacity()) * sizeof(CellCoord) + sorted_x_.capacity() * sizeof(Vec3);
}

std::vector<SegmentPair> bruteForcePairs(const Vec3* positions, std::size_t particle_count,
                                         const std::vector<CollisionSegment>& segments, double margin,
                                         std::uint32_t skip_neighbours) {
    std::vector<SegmentInfo> info(segments.size());
    validate(positions, particle_count, segments, margin, info.data());
    std::vector<SegmentPair> out;
    const auto n = static_cast<std::uint32_t>(segments.size());
    for (std::uint32_t i = 0; i < n; ++i) {
        if (segments[i].skip) continue;
        for (std::uint32_t j = i + 1; j < n; ++j) {
            if (segments[j].skip || excluded(segments[i], segments[j], skip_neighbours)) continue;
            narrowPhase(positions, segments, info.data(), margin, i, j, out);
        }
    }
    return out;
}

namespace {
/// Segments per leaf of a ChainTree. Strings' Table 1 rope (746 segments, swinging) is
/// searched in 6.7% fewer instructions a step with leaves of 16 than of 4 (8: 4.9%, 32:
/// 6.0%): a leaf pair's loops stop at the separation along the rope, where smaller leaves
/// paid a node pair's bounds and callbacks for every few segments along the diagonal. The
/// tear step of the long rope (1e5 pairs) is 0.6% cheaper, strings of 100 the same.
constexpr std::uint32_t kLeaf = 16;
constexpr std::size_t kParallelChainSegments = kParallelItems;  // a chain this long is split over the pool
bool boxesOverlap(const Vec3& alo, const Vec3& ahi, const Vec3& blo, const Vec3& bhi) {
    return alo.x() <= bhi.x() && blo.x() <= ahi.x() && alo.y() <= bhi.y() && blo.y() <= ahi.y() && alo.z() <= bhi.z() &&
           blo.z() <= ahi.z();
}

/// How far apart two nodes' boxes of axis end positions are along the coordinate axis that
/// separates them most (<= 0 where the boxes overlap).
double axisSeparation(const ChainTree::NodeBounds& a, const ChainTree::NodeBounds& b) {
    const Vec3 s = (b.lo - a.hi).cwiseMax(a.lo - b.hi);
    return std::max(s.x(), std::max(s.y(), s.z()));
}

/// Nodes of the tree that build() makes over `count` segments.
std::uint32_t treeNodes(std::uint32_t count) {
    return count <= kLeaf ? 1 : 1 + treeNodes(count / 2) + treeNodes(count - count / 2);
}

}  // namespace

std::uint32_t ChainTree::build(std::uint32_t first, std::uint32_t count, std::uint32_t& next) {
    const std::uint32_t index = next++;  // pre-order, as nodes are numbered by treeNodes
    if (count <= kLeaf) {
        Node node;
        node.first = first;
        node.count = count;
        node.lo = seg_lo_[first];
        node.hi = seg_hi_[first];
        for (std::uint32_t k = first + 1; k < first + count; ++k) {
            node.lo = node.lo.cwiseMin(seg_lo_[k]);
            node.hi = node.hi.cwiseMax(seg_hi_[k]);
        }
        if (bounded()) {
            // The bounds over every segment of the leaf, skipped ones too (a bound is all
            // the caller's proof needs; a skipped segment is never paired anyway).
            const std::vector<CollisionSegment>& segs = *segs_;
            NodeBounds b;
            const Vec3& x0 = x_[segs[first].a];
            const Vec3& t0 = sweep_.travel[segs[first].a];
            b.lo = b.hi = x0;
            b.travel_lo = b.travel_hi = t0;
            b.thickness = sweep_.thickness[first];
            b.tangent_lo = Vec3::Constant(1.0);
            b.tangent_hi = Vec3::Constant(-1.0);
            for (std::uint32_t k = first; k < first + count; ++k) {
                for (const std::uint32_t p : {segs[k].a, segs[k].b}) {
                    b.lo = b.lo.cwiseMin(x_[p]);
                    b.hi = b.hi.cwiseMax(x_[p]);
                    b.travel_lo = b.travel_lo.cwiseMin(sweep_.travel[p]);
                    b.travel_hi = b.travel_hi.cwiseMax(sweep_.travel[p]);
                }
                b.thickness = std::max(b.thickness, sweep_.thickness[k]);
                // The axis' direction; a point-like axis may point anywhere, and so may one
                // whose chain does not go on from its end (cross's separation along the
                // chain adds up the segments between two: they must be linked).
                const double length = 2.0 * info_[k].half_length;
                const Vec3 tangent = length > 0.0 ? Vec3((x_[segs[k].b] - x_[segs[k].a]) / length) : Vec3::Zero();
                const bool linked = k + 1 >= segs.size() || segs[k + 1].chain != segs[k].chain || segs[k + 1].a == segs[k].b;
                const bool known = linked && length > 0.0 && tangent.allFinite();
                b.tangent_lo = b.tangent_lo.cwiseMin(known ? tangent : Vec3::Constant(-1.0));
                b.tangent_hi = b.tangent_hi.cwiseMax(known ? tangent : Vec3::Constant(1.0));
            }
            bounds_[index] = b;
        }
        nodes_[index] = node;
    } else {
        const std::uint32_t half = count / 2;
        const std::uint32_t left = build(first, half, next);
        const std::uint32_t right = build(first + half, count - half, next);
        join(index, first, count, left, right);
    }
    return index;
}

void ChainTree::join(std::uint32_t index, std::uint32_t first, std::uint32_t count, std::uint32_t left, std::uint32_t right) {
    Node node;
    node.first = first;
    node.count = count;
    node.left = left;
    node.right = right;
    node.lo = nodes_[left].lo.cwiseMin(nodes_[right].lo);
    node.hi = nodes_[left].hi.cwiseMax(nodes_[right].hi);
    if (bounded()) {
        const NodeBounds& l = bounds_[left];
        const NodeBounds& r = bounds_[right];
        NodeBounds& b = bounds_[index];
        b.lo = l.lo.cwiseMin(r.lo);
        b.hi = l.hi.cwiseMax(r.hi);
        b.travel_lo = l.travel_lo.cwiseMin(r.travel_lo);
        b.travel_hi = l.travel_hi.cwiseMax(r.travel_hi);
        b.tangent_lo = l.tangent_lo.cwiseMin(r.tangent_lo);
        b.tangent_hi = l.tangent_hi.cwiseMax(r.tangent_hi);
        b.thickness = std::max(l.thickness, r.thickness);
    }
    nodes_[index] = node;
}

void ChainTree::splitChain(std::size_t c, ThreadPool& pool, bool self_free) {
    // The root's children are built on two threads, each numbering its nodes from where
    // the serial pre-order would (the left subtree right after the root, the right one
    // after it); then the root's self pairs as three parts, self(left), self(right) and
    // cross(left, right), each into a buffer of its own, appended in the serial order.
    const std::uint32_t first = chain_first_[c], count = chain_count_[c], root = chain_node_[c];
    const std::uint32_t half = count / 2;
    const std::uint32_t left = root + 1, right = left + treeNodes(half);
    pool.forEach(2, [&](std::size_t k) {
        std::uint32_t next = k == 0 ? left : right;
        if (k == 0)
            build(first, half, next);
        else
            build(first + half, count - half, next);
    });
    join(root, first, count, left, right);
    roots_[c] = root;
    chain_out_[c].clear();
    chain_rejects_[c] = 0;
    if (self_free) return;
    std::size_t rejects[3] = {0, 0, 0};
    Vec3 along;
    const Vec3* forward = forwardDirection(root, along) ? &along : nullptr;
    pool.forEach(3, [&](std::size_t k) {
        split_out_[k].clear();
        if (k == 0) self(left, split_out_[k], rejects[k], forward);
        if (k == 1) self(right, split_out_[k], rejects[k], forward);
        if (k == 2) cross(left, right, split_out_[k], rejects[k], forward);
    });
    for (const std::vector<SegmentPair>& part : split_out_) chain_out_[c].insert(chain_out_[c].end(), part.begin(), part.end());
    chain_rejects_[c] = rejects[0] + rejects[1] + rejects[2];
}

void ChainTree::test(std::uint32_t i, std::uint32_t j, std::vector<SegmentPair>& out) const {
    const std::vector<CollisionSegment>& segs = *segs_;
    if (segs[i].skip || segs[j].skip || excluded(segs[i], segs[j], skip_)) return;
    if (!boxesOverlap(seg_lo_[i], seg_hi_[i], seg_lo_[j], seg_hi_[j])) return;
    if (reject_) {
        // The narrow phase's own first rejection (the same bounding spheres), then the
        // caller's: what either drops is never output.
        const double reach = segs[i].radius + segs[j].radius + margin_;
        const double sphere = info_[i].half_length + info_[j].half_length + reach;
        if ((info_[i].mid - info_[j].mid).squaredNorm() > sphere * sphere * kSlack) return;
        if (reject_(keep_context_, std::min(i, j), std::max(i, j))) return;
    }
    const std::size_t before = out.size();
    narrowPhase(x_, segs, info_.data(), margin_, std::min(i, j), std::max(i, j), out);
    if (keep_ && out.size() > before && !keep_(keep_context_, out.back())) out.pop_back();
}

bool ChainTree::forwardDirection(std::uint32_t index, Vec3& along) const {
    if (!bounded()) return false;
    // The middle of the tangents' box, and the least of t . u over the box (per
    // coordinate, the end that makes the product smallest): every tangent has at least
    // that much along u. Kept only with a clear margin (1e-6) over rounding.
    const NodeBounds& b = bounds_[index];
    const Vec3 middle = 0.5 * (b.tangent_lo + b.tangent_hi);
    const double norm = middle.norm();
    if (!(norm > 0.1)) return false;
    along = middle / norm;
    double least = 0.0;
    for (int c = 0; c < 3; ++c) least += std::min(along[c] * b.tangent_lo[c], along[c] * b.tangent_hi[c]);
    return least > 1e-6;
}

void ChainTree::self(std::uint32_t index, std::vector<SegmentPair>& out, std::size_t& rejects, const Vec3* along) const {
    const Node& node = nodes_[index];
    if (node.left == 0) {
        // Within a leaf, a pair that the separation along `along` settles (see cross). The
        // segments right after i along its chain, within the skip, are never pairs
        // (test's `excluded`): j starts past them.
        const double needed = along ? sweep_.separation(keep_context_, bounds_[index], bounds_[index]) : 0.0;
        const std::vector<CollisionSegment>& segs = *segs_;
        const std::uint32_t end = node.first + node.count;
        for (std::uint32_t i = node.first; i < end; ++i) {
            std::uint32_t start = i + 1;
            while (start < end && start - i <= skip_ && segs[start].index_in_chain - segs[i].index_in_chain == start - i) ++start;
            for (std::uint32_t j = start; j < end; ++j) {
                if (along && (x_[segs[j].a] - x_[segs[i].b]).dot(*along) > needed) break;  // and every later j
                test(i, j, out);
            }
        }
        return;
    }
    Vec3 own;
    if (!along && forwardDirection(index, own)) along = &own;
    self(node.left, out, rejects, along);
    self(node.right, out, rejects, along);
    cross(node.left, node.right, out, rejects, along);
}

void ChainTree::cross(std::uint32_t a, std::uint32_t b, std::vector<SegmentPair>& out, std::size_t& rejects,
                      const Vec3* along) const {
    const Node& na = nodes_[a];
    const Node& nb = nodes_[b];
    if (!boxesOverlap(na.lo, na.hi, nb.lo, nb.hi)) return;
    // Neighbours along one chain closer than the skip are never pairs: ranges entirely
    // within the skip of each other are done.
    const CollisionSegment& sa = (*segs_)[na.first];
    const CollisionSegment& sb = (*segs_)[nb.first];
    if (sa.chain == sb.chain) {
        const std::uint32_t lo_a = sa.index_in_chain, hi_a = lo_a + na.count - 1;
        const std::uint32_t lo_b = sb.index_in_chain, hi_b = lo_b + nb.count - 1;
        const std::uint32_t far = std::max(hi_b > lo_a ? hi_b - lo_a : lo_a - hi_b, hi_a > lo_b ? hi_a - lo_b : lo_b - hi_a);
        if (far <= skip_) return;
    }
    // Along a chain whose segments all point forward along `along` (from a's first to b's
    // last; a's come first), a point of segment i of a and one of segment j of b are at
    // least (x_j,start - x_i,end) . along apart along it: the rest of segment i and the
    // start of segment j only add to that, as do the segments between. The smallest of
    // these, over a's last and b's first segment, bounds every pair's.
    const std::vector<CollisionSegment>& segs = *segs_;
    // The caller's proof that it drops every pair below these two nodes (a rope swinging
    // as a whole: its segments' swept boxes overlap, their relative travel is small): the
    // nodes further apart than `needed` along the chain, or along a coordinate axis.
    const double needed = bounded() ? sweep_.separation(keep_context_, bounds_[a], bounds_[b]) : 0.0;
    const bool apart_along = along && (x_[segs[nb.first].a] - x_[segs[na.first + na.count - 1].b]).dot(*along) > needed;
    if (apart_along || (bounded() && axisSeparation(bounds_[a], bounds_[b]) > needed)) {
        ++rejects;
        return;
    }
    if (na.left == 0 && nb.left == 0) {
        // The separation grows with j (each segment adds to it): past the first j it
        // settles, it settles every later one too.
        for (std::uint32_t i = na.first; i < na.first + na.count; ++i)
            for (std::uint32_t j = nb.first; j < nb.first + nb.count; ++j) {
                if (along && (x_[segs[j].a] - x_[segs[i].b]).dot(*along) > needed) break;
                test(i, j, out);
            }
        return;
    }
    if (nb.left == 0 || (na.left != 0 && na.count >= nb.count)) {
        cross(na.left, b, out, rejects, along);
        cross(na.right, b, out, rejects, along);
    } else {
        cross(a, nb.left, out, rejects, along);
        cross(a, nb.right, out, rejects, along);
    }
}

void ChainTree::findPairs(const Vec3* positions, const std::vector<CollisionSegment>& segments, double margin,
                          std::vector<SegmentPair>& out, std::uint32_t skip_neighbours, ThreadPool* pool, Filter keep,
                          const void* context, Reject reject, const Sweep* sweep, const std::uint8_t* self_free) {
    out.clear();
    keep_ = keep;
    reject_ = reject;
    sweep_ = sweep && sweep->separation && sweep->travel && sweep->thickness ? *sweep : Sweep{};
    keep_context_ = context;
    x_ = positions;
    segs_ = &segments;
    margin_ = margin;
    skip_ = skip_neighbours;
    auto each = [pool](std::size_t count, auto&& fn) {
        if (pool) pool->forEach(count, fn);
        else
            for (std::size_t i = 0; i < count; ++i) fn(i);
    };
    const std::size_t m = segments.size();
    seg_lo_.resize(m);
    seg_hi_.resize(m);
    info_.resize(m);
    const double inf = std::numeric_limits<double>::infinity();
    const std::size_t chunks = std::min<std::size_t>(m, 64);
    each(chunks, [&](std::size_t chunk) {
        for (std::size_t k = m * chunk / chunks; k < m * (chunk + 1) / chunks; ++k) {
            const CollisionSegment& sg = segments[k];
            const Vec3& a = positions[sg.a];
            const Vec3& b = positions[sg.b];
            info_[k].mid = 0.5 * (a + b);
            info_[k].length2 = (b - a).squaredNorm();
            info_[k].half_length = 0.5 * std::sqrt(info_[k].length2);
            if (sg.skip) {
                seg_lo_[k] = Vec3::Constant(inf);
                seg_hi_[k] = Vec3::Constant(-inf);
                continue;
            }
            const Vec3 grow = Vec3::Constant(sg.radius + 0.5 * margin);
            seg_lo_[k] = a.cwiseMin(b) - grow;
            seg_hi_[k] = a.cwiseMax(b) + grow;
        }
    });
    // One tree per chain (runs of equal `chain`); node 0 is a dummy so that 0 means "leaf".
    // Each chain's nodes are a range of their own, numbered beforehand.
    chain_first_.clear();
    chain_count_.clear();
    chain_node_.clear();
    std::uint32_t nodes = 1;
    for (std::size_t first = 0; first < m;) {
        std::size_t last = first + 1;
        while (last < m && segments[last].chain == segments[first].chain) ++last;
        chain_first_.push_back(static_cast<std::uint32_t>(first));
        chain_count_.push_back(static_cast<std::uint32_t>(last - first));
        chain_node_.push_back(nodes);
        nodes += treeNodes(static_cast<std::uint32_t>(last - first));
        first = last;
    }
    nodes_.resize(nodes);
    nodes_[0] = Node{};
    if (bounded()) bounds_.resize(nodes);
    const std::size_t chains = chain_first_.size();
    if (chain_out_.size() < chains) chain_out_.resize(chains);
    roots_.resize(chains);
    chain_rejects_.resize(chains);
    // A chain of kParallelChainSegments or more, where the pool runs in parallel, is split
    // over it by itself (splitChain: a long rope alone uses every core); the others run
    // one per thread. The nodes and pairs are the same either way.
    auto big = [&](std::size_t c) { return pool && pool->parallel() && chain_count_[c] >= kParallelChainSegments; };
    each(chains, [&](std::size_t c) {
        if (big(c)) return;
        std::uint32_t next = chain_node_[c];
        roots_[c] = build(chain_first_[c], chain_count_[c], next);
        chain_out_[c].clear();
        chain_rejects_[c] = 0;
        if (!(self_free && self_free[c])) self(roots_[c], chain_out_[c], chain_rejects_[c]);
    });
    for (std::size_t c = 0; c < chains; ++c)
        if (big(c)) splitChain(c, *pool, self_free && self_free[c]);
    for (std::size_t c = 0; c < chains; ++c) out.insert(out.end(), chain_out_[c].begin(), chain_out_[c].end());
    // Chains against each other: sweep the root boxes along the axis on which their
    // centres spread most (strings side by side all overlap along their own length: swept
    // along it, every root met every other), sorted by their lower bound on it, ties by
    // position in the list: deterministic. The pairs are the same on any axis; only the
    // order of the output changes.
    int axis = 0;
    if (roots_.size() > 2) {
        Vec3 mean = Vec3::Zero(), square = Vec3::Zero();
        for (std::uint32_t r : roots_) {
            const Vec3 c = 0.5 * (nodes_[r].lo + nodes_[r].hi);
            mean += c;
            square += c.cwiseProduct(c);
        }
        const double k = static_cast<double>(roots_.size());
        const Vec3 spread = square / k - (mean / k).cwiseProduct(mean / k);
        if (spread.allFinite()) spread.maxCoeff(&axis);
    }
    order_ = roots_;
    std::sort(order_.begin(), order_.end(), [&](std::uint32_t l, std::uint32_t r) {
        const double a = nodes_[l].lo[axis], b = nodes_[r].lo[axis];
        return a < b || (a == b && l < r);
    });
    // The pairs of roots the sweep meets, in its order; each pair's descent on the pool
    // into a buffer of its own, appended in that order.
    root_pairs_.clear();
    for (std::size_t i = 0; i < order_.size(); ++i) {
        const Node& a = nodes_[order_[i]];
        for (std::size_t j = i + 1; j < order_.size() && nodes_[order_[j]].lo[axis] <= a.hi[axis]; ++j)
            root_pairs_.emplace_back(std::min(order_[i], order_[j]), std::max(order_[i], order_[j]));
    }
    if (root_out_.size() < root_pairs_.size()) root_out_.resize(root_pairs_.size());
    root_rejects_.resize(root_pairs_.size());
    each(root_pairs_.size(), [&](std::size_t k) {
        root_out_[k].clear();
        root_rejects_[k] = 0;
        cross(root_pairs_[k].first, root_pairs_[k].second, root_out_[k], root_rejects_[k]);
    });
    for (std::size_t k = 0; k < root_pairs_.size(); ++k) out.insert(out.end(), root_out_[k].begin(), root_out_[k].end());
}

std::size_t ChainTree::lastNodeRejects() const {
    std::size_t n = 0;
    for (std::size_t c = 0; c < roots_.size(); ++c) n += chain_rejects_[c];
    for (std::size_t k = 0; k < root_pairs_.size(); ++k) n += root_rejects_[k];
    return n;
}

}  // namespace tearables::detail
