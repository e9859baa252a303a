// The uniform hash grid of reference_grid.hpp; the narrow phase is the library's
// (collision/grid.hpp), so the grid, brute force and ChainTree report the same pairs.
#include "collision/reference_grid.hpp"

#include <algorithm>
#include <limits>
#include <string>

namespace tearables::reference {

using detail::excludedPair;
using detail::kPairSlack;
using detail::narrowPhase;

namespace {

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
                if (excludedPair(si, sj, skip_neighbours)) continue;
                // The endpoint pair of this visit: u on segment i, v on segment j.
                const std::uint32_t u = a_first ? pa : pb;
                const std::uint32_t v = a_first ? pb : pa;
                const std::uint32_t ends_i[2] = {si.a, si.b};
                const std::uint32_t ends_j[2] = {sj.a, sj.b};
                const int here = 2 * (si.a == u ? 0 : 1) + (sj.a == v ? 0 : 1);
                double d12sq = 0.0;
                if constexpr (!kSeven) {
                    const double reach = si.radius + sj.radius + margin;
                    d12sq = (0.25 * (info[i].length2 + info[j].length2) + reach * reach) * kPairSlack;
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
    const double dmax2 = (0.25 * (v.max_length2 + v.max_length2) + max_reach * max_reach) * kPairSlack;
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
            if (segments[j].skip || excludedPair(segments[i], segments[j], skip_neighbours)) continue;
            narrowPhase(positions, segments, info.data(), margin, i, j, out);
        }
    }
    return out;
}
}  // namespace tearables::reference
