// String-string and self collision (Strings Sec. 6): every segment is a capsule; two
// capsules overlap when their axes come closer than the sum of the radii.
//
// The strings that touch are solved together (solveStringCluster, cluster_solve.cpp): one
// Newton method on their energies plus contact penalties and Coulomb friction on the
// contact points' relative motion, so momentum is exchanged, the strain limit stays exact
// and the step ends without overlaps (why: docs/notes-string-collision.md). Pairs come
// from the segments at the start of the step, each capsule grown by its ends' travel
// (ChainTree), so a pair that passed through is found and its start direction tells the
// sides. In the momentum-balance tension a pressed particle loses the contact force's
// directions (row_projector, as for rigid contacts). The clean-up projection (finish)
// runs after the tension stage.
#include "string/string_pairs.hpp"

#include "base/union_find.hpp"
#include "collision/capsule.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace tearables::detail {

namespace {

/// Coulomb friction between strings (fibre on fibre, dry nylon and cotton: about 0.2-0.4).
constexpr double kStringFriction = 0.3;
/// The clean-up projection after the tension stage (finish): at most this many
/// Gauss-Seidel sweeps, stopped once no pair overlaps by more than the tolerance
/// (fraction of its thickness).
constexpr int kStringCleanupSweeps = 8;
constexpr double kStringCleanupTolerance = 1e-3;
/// A pair whose axes are closer than this fraction of the thickness at the start of a step
/// is no contact: no solver step ends that deep, so something else put it there (strings
/// created through each other, a pin moved through one), and it has no side to be pushed
/// to. It comes apart by itself and is a contact again once apart by the thickness.
constexpr double kStringDeepStart = 0.5;
/// Axes closer than this fraction of the thickness have no reliable direction of their
/// own: the direction at the start of the step is used.
constexpr double kStringAxisContact = 1e-3;
/// Pairs are searched for with each capsule grown by its ends' travel in the step and by
/// this fraction of its radius (slack for what the joint solve changes): every pair that
/// can meet during the step is found, and no pair that cannot.
constexpr double kStringReach = 1.0;
/// A pair of the swept search whose axes are, after the strings' own solves, farther apart
/// on their starting side than (1 + this) times the thickness plus twice the relative
/// travel of its ends is not solved: the joint solve moves a string by about that.
constexpr double kStringNear = 0.25;
/// Pairs within this fraction of the thickness of touching count as colliding.
constexpr double kStringTouchSlop = 0.1;

/// Segments of one string closer along it than the capsules are thick touch their
/// neighbours when the string is straight: segments k apart have (k - 1) L of axis
/// between them, so pairs with k <= 1 + ceil(2 r / L) are not collisions. (A property
/// of the string, not of the search margin: only true overlaps act.)
std::uint32_t stringContactSkip(double thickest_radius, double shortest_segment) {
    return static_cast<std::uint32_t>(1.0 + std::ceil(2.0 * thickest_radius / shortest_segment));
}

}  // namespace

std::size_t StringPairs::lastSelfFreeStrings() const {
    return static_cast<std::size_t>(std::count(self_free_.begin(), self_free_.end(), std::uint8_t{1}));
}

void StringPairs::findPairs() {
    const std::vector<StringState>& strings = *strings_;
    ThreadPool& pool = *pool_;
    string_pairs_.clear();
    deep_next_.clear();
    // The segments of the live strings, string after string, each string's run filled
    // on the pool (where it starts is known beforehand).
    pair_strings_.clear();
    std::size_t particle_count = 0, segment_count = 0;
    for (std::size_t i = 0; i < strings.size(); ++i) {
        const StringState& s = strings[i];
        if (!s.alive || s.frozen) continue;
        pair_strings_.push_back({static_cast<std::uint32_t>(i), particle_count, segment_count, 0.0, 0.0, true, -1.0, 0.0});
        particle_count += s.particles();
        segment_count += s.segments();
    }
    grid_positions_.resize(particle_count);
    grid_travel_.resize(particle_count);
    grid_thickness_.resize(segment_count);
    grid_segments_.resize(segment_count);
    // A single string is first scanned for selfPairFree alone: proved free of self pairs,
    // it needs no search. Otherwise each scan fills its run of the search's arrays too.
    const bool alone = pair_strings_.size() == 1;
    pool.forEach(pair_strings_.size(), [&](std::size_t k) {
        if (alone)
            scanString<false>(pair_strings_[k]);
        else
            scanString<true>(pair_strings_[k]);
    });
    double thickest = 0.0, shortest_segment = 1e300, extent = 0.0;
    for (const PairString& ps : pair_strings_) {
        thickest = std::max(thickest, ps.thickest);
        extent = std::max(extent, ps.extent);
        shortest_segment = std::min(shortest_segment, strings[ps.string].shortest_rest);
    }
    tree_searched_ = false;
    grid_pairs_.clear();
    grid_rounding_ = 1e-15 * (2.0 * extent + 1.0);
    const std::uint32_t skip = stringContactSkip(thickest, shortest_segment);
    self_free_.assign(pair_strings_.size(), 0);
    if (straight_strings_skip)
        for (std::size_t k = 0; k < pair_strings_.size(); ++k) self_free_[k] = selfPairFree(pair_strings_[k], skip);
    if (alone && self_free_[0]) {
        deep_pairs_.clear();
        return;
    }
    if (alone) scanString<true>(pair_strings_[0]);
    bool finite_state = true;
    for (const PairString& ps : pair_strings_) finite_state = finite_state && ps.finite;
    if (grid_segments_.size() < 2 || !finite_state) {
        deep_pairs_.clear();
        return;
    }
    searchTree(skip);
    sortContacts();
}

/// The swept capsules' overlaps through a box tree per string (ChainTree): the tree asks
/// judgePair about each pair as it finds it and keeps those not dropped (most are); the
/// kept ones are judged again on the pool, their verdicts in the pairs' order.
void StringPairs::searchTree(std::uint32_t skip) {
    ThreadPool& pool = *pool_;
    auto keep = [](const void* self, const SegmentPair& pair) {
        // judgePair writes what it reads of the contact first: a scratch per thread,
        // not a StringPairContact of defaults built for every candidate.
        thread_local StringPairContact scratch;
        return static_cast<const StringPairs*>(self)->judgePair(pair, scratch) != kPairDropped;
    };
    auto reject = [](const void* self, std::uint32_t i, std::uint32_t j) {
        return static_cast<const StringPairs*>(self)->surelyDropped(i, j);
    };
    // Whole node pairs dropped at once (nodesSeparationNeeded): a rope swinging as a whole
    // has its swept boxes overlap far along it, their relative travel small.
    auto separation_needed = [](const void* self, const ChainTree::NodeBounds& a,
                                const ChainTree::NodeBounds& b) {
        return static_cast<const StringPairs*>(self)->nodesSeparationNeeded(a, b);
    };
    const ChainTree::Sweep sweep{grid_travel_.data(), grid_thickness_.data(), separation_needed};
    tree_.findPairs(grid_positions_.data(), grid_segments_, 0.0, grid_pairs_, skip, &pool, keep, this, reject,
                   node_pruning ? &sweep : nullptr, self_free_.data());
    tree_searched_ = true;
    pair_verdict_.resize(grid_pairs_.size());
    pair_contact_.resize(grid_pairs_.size());
    const std::size_t chunks = std::min<std::size_t>(grid_pairs_.size(), 64);
    pool.forEach(chunks, [&](std::size_t chunk) {
        const std::size_t lo = grid_pairs_.size() * chunk / chunks, hi = grid_pairs_.size() * (chunk + 1) / chunks;
        for (std::size_t i = lo; i < hi; ++i) pair_verdict_[i] = judgePair(grid_pairs_[i], pair_contact_[i]);
    });
}

/// The contacts sorted by key (string, segment, partner, partner segment), for the warm
/// start's merge and the deep pairs' binary search: the keys sorted with their indices,
/// the contacts copied once. A key is unique (the search reports a pair once).
void StringPairs::sortContacts() {
    contact_order_.clear();
    for (std::size_t i = 0; i < grid_pairs_.size(); ++i) {
        const StringPairContact& c = pair_contact_[i];
        const PairKey key = c.key();
        if (pair_verdict_[i] == kPairDeep) deep_next_.push_back(key);
        if (pair_verdict_[i] == kPairContact) contact_order_.emplace_back(key, static_cast<std::uint32_t>(i));
    }
    std::sort(contact_order_.begin(), contact_order_.end());
    string_pairs_.reserve(contact_order_.size());
    for (const auto& [key, i] : contact_order_) string_pairs_.push_back(pair_contact_[i]);
    std::sort(deep_next_.begin(), deep_next_.end());
    deep_pairs_.swap(deep_next_);
}

/// Scans a live string for the search: its largest |x|_1 and |x_prev|_1 (ps.extent),
/// thickest radius and selfPairFree's sums: the least advance of a segment along the unit
/// chord u of the start positions, d . u - 1e-14 |d|_1 (d = x_prev[j+1] - x_prev[j]; -1
/// where u or an advance is missing), and the largest |t_{j+1} - t_j| of the travels
/// t = x - x_prev, times 1 + 1e-12. With `fill`, also its run of the search's arrays and
/// ps.finite. Ranges on the pool give the same result for any cut; a NaN fails the test.
template <bool fill>
void StringPairs::scanString(PairString& ps) {
    const std::vector<StringState>& strings = *strings_;
    ThreadPool& pool = *pool_;
    const StringState& s = strings[ps.string];
    const std::size_t n = s.particles();
    const Vec3 chord = s.x_prev.back() - s.x_prev.front();
    const double chord_length = chord.norm();
    const bool along_chord = chord_length > 0.0 && std::isfinite(chord_length);
    const Vec3 u = along_chord ? Vec3(chord / chord_length) : Vec3::Zero();
    struct Sums {
        double extent = 0.0, thickest = 0.0;
        double advance = std::numeric_limits<double>::infinity(), shear2 = 0.0;
        bool finite = true;
        void least(double v) { if (!(v >= advance)) advance = v; }
        void most(double v) { if (!(v <= shear2)) shear2 = v; }
    };
    Vec3* positions = grid_positions_.data() + ps.particle_base;
    Vec3* moved = grid_travel_.data() + ps.particle_base;
    CollisionSegment* segments = grid_segments_.data() + ps.segment_base;
    double* thickness = grid_thickness_.data() + ps.segment_base;
    const auto base = static_cast<std::uint32_t>(ps.particle_base);
    // How far particle p travelled this step (t = x - x_prev given), to its prediction or
    // in its string's own solve (sqrt is monotone and correctly rounded: the larger of
    // the two norms, bit for bit, with one square root).
    auto travel = [&s](std::size_t p, const Vec3& t) {
        return std::sqrt(std::max(t.squaredNorm(), (s.x_pred[p] - s.x_prev[p]).squaredNorm()));
    };
    Sums range_sums[kMaxRanges];
    forRanges(&pool, n, kParallelItems, [&](std::size_t p0, std::size_t p1, std::size_t part) {
        Sums sums;
        // The previous particle's travel, carried: each particle's is found once.
        Vec3 before = p0 > 0 ? Vec3(s.x[p0 - 1] - s.x_prev[p0 - 1]) : Vec3::Zero();
        double previous = 0.0;
        if constexpr (fill) previous = p0 > 0 ? travel(p0 - 1, before) : 0.0;
        for (std::size_t p = p0; p < p1; ++p) {
            sums.extent = std::max(sums.extent, std::max(s.x[p].cwiseAbs().sum(), s.x_prev[p].cwiseAbs().sum()));
            const Vec3 t = s.x[p] - s.x_prev[p];
            double now = 0.0;
            if constexpr (fill) {
                now = travel(p, t);
                positions[p] = s.x_prev[p];  // pairs from the start of the step (swept)
                moved[p] = t;
            }
            if (p > 0) {
                const std::size_t j = p - 1;
                sums.thickest = std::max(sums.thickest, s.radius[j]);
                const Vec3 d = s.x_prev[p] - s.x_prev[j];
                sums.least(d.dot(u) - 1e-14 * d.cwiseAbs().sum());
                sums.most((t - before).squaredNorm());
                if constexpr (fill) {
                    CollisionSegment& seg = segments[j];
                    seg.a = base + static_cast<std::uint32_t>(j);
                    seg.b = seg.a + 1;
                    seg.chain = ps.string;
                    seg.index_in_chain = static_cast<std::uint32_t>(j);
                    // The capsule at the start of the step, grown by its ends' travel and
                    // by kStringReach of its radius for what the joint solve changes.
                    seg.radius = s.radius[j] * (1.0 + kStringReach) + std::max(previous, now);
                    seg.skip = s.broken[j] != 0;
                    thickness[j] = s.radius[j];
                    sums.finite = sums.finite && std::isfinite(seg.radius);
                }
            }
            previous = now;
            before = t;
        }
        range_sums[part] = sums;
    });
    Sums total;
    for (const Sums& sums : range_sums) {  // (ranges not run hold the identities)
        total.extent = std::max(total.extent, sums.extent);
        total.thickest = std::max(total.thickest, sums.thickest);
        total.least(sums.advance);
        total.most(sums.shear2);
        total.finite = total.finite && sums.finite;
    }
    ps.extent = total.extent;
    ps.thickest = total.thickest;
    ps.advance = along_chord && total.advance > 0.0 ? total.advance : -1.0;
    ps.shear = std::sqrt(total.shear2) * (1.0 + 1e-12);
    ps.finite = total.finite;
}

/// True when judgePair would drop every pair of a string's own segments this step, by its
/// shape alone (scanString's sums): a rope swinging or hanging nearly straight, whose self
/// search would otherwise descend its whole tree along the diagonal to drop every pair.
///
/// With u the unit chord of the start positions and every segment advancing along u by at
/// least `advance` > 0 (less 1e-14 |d|_1 a segment for rounding), segments i < j, g = j - i,
/// are separated along u at the start by at least (g - 1) advance, and the relative travel
/// of their ends is at most (g + 1) `shear`. surelyDropped's argument drops a pair with
/// separation sep > c + k r (k = 1 + 2 (1 + 1e-6) <= 4; c = 2 (1 + kStringNear)(1 + 1e-6)
/// times the thickest radius, plus grid_rounding_). Pairs have g > skip, and
/// (g - 1) advance - 4 (g + 1) shear grows with g where advance > 4 shear, so g = skip + 1
/// decides for all. Such a pair is not deep either: its start distance exceeds c > the gap.
bool StringPairs::selfPairFree(const PairString& ps, std::uint32_t skip) const {
    const double c = 2.0 * (1.0 + kStringNear) * ps.thickest * (1.0 + 1e-6) + grid_rounding_;
    const double travel = 4.0 * ps.shear;
    const double g = static_cast<double>(skip) + 1.0;
    return ps.advance > travel && (g - 1.0) * ps.advance - (g + 1.0) * travel > c;
}

/// What findPairs makes of a pair of the swept search: no contact, a pair that
/// is (still) deep (c's key is remembered), or a contact (c). Reads only.
std::uint8_t StringPairs::judgePair(const SegmentPair& pair, StringPairContact& c) const {
    const std::vector<StringState>& strings = *strings_;
    const CollisionSegment& a = grid_segments_[pair.first];
    const CollisionSegment& b = grid_segments_[pair.second];
    // Only the key and the gap until the pair is kept (most are not).
    c.string = a.chain;
    c.segment = a.index_in_chain;
    c.partner = b.chain;
    c.partner_segment = b.index_in_chain;
    c.gap = strings[c.string].radius[c.segment] + strings[c.partner].radius[c.partner_segment];
    // Deep at the start, or still coming apart from being deep: no contact (see
    // kStringDeepStart), and remembered for the next step.
    const PairKey key = c.key();
    const bool was_deep = std::binary_search(deep_pairs_.begin(), deep_pairs_.end(), key);
    if (pair.distance < (was_deep ? 1.0 : kStringDeepStart) * c.gap) {
        return kPairDeep;
    }
    // Apart after the strings' own solves, by more than kStringNear of the thickness and
    // on their starting side: no contact this step (most pairs of the swept search).
    const StringState& sa = strings[c.string];
    const StringState& sb = strings[c.partner];
    // Relative travel of the pair's ends over the step: the axes' distance at any
    // time of the step differs from the end's by at most this.
    double relative = 0.0;
    for (std::size_t i = c.segment; i <= c.segment + 1u; ++i)
        for (std::size_t k = c.partner_segment; k <= c.partner_segment + 1u; ++k)
            relative = std::max(relative, ((sa.x[i] - sa.x_prev[i]) - (sb.x[k] - sb.x_prev[k])).squaredNorm());
    relative = std::sqrt(relative);
    const double apart = (1.0 + kStringNear) * c.gap + 2.0 * relative;
    // Most pairs are dropped here without their closest points: separated along the start
    // normal n by more than `apart`, the closest points p, q have |p - q| >= (p - q).n >
    // apart, so the test below would drop the pair too (margins of 1e-6 and the positions'
    // rounding keep that true in floating point).
    {
        const Vec3& a0 = sa.x[c.segment];
        const Vec3& a1 = sa.x[c.segment + 1];
        const Vec3& b0 = sb.x[c.partner_segment];
        const Vec3& b1 = sb.x[c.partner_segment + 1];
        const Vec3& n = pair.normal;
        const double separation = std::min(n.dot(a0), n.dot(a1)) - std::max(n.dot(b0), n.dot(b1));
        const double rounding = 1e-15 * (a0.cwiseAbs().sum() + b0.cwiseAbs().sum() + 1.0);
        if (separation > apart * (1.0 + 1e-6) + rounding) return kPairDropped;
    }
    const SegmentClosest now = closestPointsOfSegments(
        sa.x[c.segment], sa.x[c.segment + 1], sb.x[c.partner_segment], sb.x[c.partner_segment + 1]);
    if (now.distance > apart && (now.p - now.q).dot(pair.normal) > 0.0) return kPairDropped;
    const double gap = c.gap;
    c = StringPairContact{};
    c.string = a.chain;
    c.segment = a.index_in_chain;
    c.partner = b.chain;
    c.partner_segment = b.index_in_chain;
    c.s = pair.s;
    c.partner_s = pair.t;
    c.start_normal = pair.normal;
    c.start_distance = pair.distance;
    c.normal = pair.normal;
    c.gap = gap;
    c.friction = kStringFriction;
    return kPairContact;
}

/// True when judgePair would surely drop the pair of segments i < j (of grid_segments_),
/// decided before their closest points: separated at the start along some unit u (here
/// between their midpoints) by sep > r, the relative travel of their ends, every point a of
/// one and b of the other has now (a - b).n0 >= d0 - r > 0 (n0, d0: the start closest
/// points' direction and distance, d0 >= sep; a - b moves by a convex combination of the
/// ends' relative motions). So the pair is on its starting side, not deep, and at least
/// sep - r apart: dropped when that is beyond judgePair's distance, with a rounding margin.
///
/// With w = (a0 + a1) - (b0 + b1), L = |w|, the separation along u = w / L is
/// (L^2 - |w.(a1 - a0)| - |w.(b1 - b0)|) / (2 L); the test sep - r > k r + c
/// (k = 1 + 2 (1 + 1e-6), c = (1 + kStringNear) gap (1 + 1e-6) + rounding) is multiplied by
/// 2 L and squared, for one square root (L) and none for r (r^2 with a relative 1e-12).
/// Its errors, ~1e-16 |x|, are far below grid_rounding_ (>= judgePair's own).
bool StringPairs::surelyDropped(std::uint32_t i, std::uint32_t j) const {
    const CollisionSegment& a = grid_segments_[i];
    const CollisionSegment& b = grid_segments_[j];
    const Vec3& a0 = grid_positions_[a.a];
    const Vec3& a1 = grid_positions_[a.b];
    const Vec3& b0 = grid_positions_[b.a];
    const Vec3& b1 = grid_positions_[b.b];
    const Vec3 w = (a0 + a1) - (b0 + b1);
    const double length2 = w.squaredNorm();
    const double length = std::sqrt(length2);
    const double c = (1.0 + kStringNear) * (grid_thickness_[i] + grid_thickness_[j]) * (1.0 + 1e-6) + grid_rounding_;
    // 2 L (sep - c), when the pair is separated along u by more than c.
    const double room = length2 - std::abs(w.dot(a1 - a0)) - std::abs(w.dot(b1 - b0)) - 2.0 * c * length;
    if (!(room > 0.0)) return false;
    // The relative travel (squared) as judgePair computes it, from the set-up's
    // x - x_prev (the same values).
    double relative2 = 0.0;
    for (std::uint32_t pa : {a.a, a.b})
        for (std::uint32_t pb : {b.a, b.b}) relative2 = std::max(relative2, (grid_travel_[pa] - grid_travel_[pb]).squaredNorm());
    constexpr double k = 1.0 + 2.0 * (1.0 + 1e-6);
    return room * room > 4.0 * length2 * (k * k * (1.0 + 1e-12)) * relative2;
}

/// The separation along a unit direction u beyond which judgePair drops every pair of node
/// a's segments with node b's (ChainTree::NodeSeparation tests it along the axes and along
/// directions it finds): surelyDropped's argument for all pairs at once. The start boxes'
/// separation along u bounds each pair's from below; the travel boxes bound each end pair's
/// relative travel, |t_a - t_b| <= |max(ta_hi - tb_lo, tb_hi - ta_lo)| per coordinate, by R;
/// the thicknesses bound each gap. So sep - R > (1 + kStringNear) (g_a + g_b) + 2 R meets
/// surelyDropped's condition for every pair. Margins: 1e-12 on R for the norms' summation
/// order, 1e-6 and grid_rounding_ as in surelyDropped, and a second grid_rounding_ for a
/// separation along a direction the tree found.
double StringPairs::nodesSeparationNeeded(const ChainTree::NodeBounds& a, const ChainTree::NodeBounds& b) const {
    const Vec3 d = (a.travel_hi - b.travel_lo).cwiseMax(b.travel_hi - a.travel_lo);
    const double relative = std::sqrt(d.x() * d.x() + d.y() * d.y() + d.z() * d.z()) * (1.0 + 1e-12);
    const double apart = (1.0 + kStringNear) * (a.thickness + b.thickness) + 2.0 * relative;
    return relative + apart * (1.0 + 1e-6) + 2.0 * grid_rounding_;
}

/// After every string's own strain limit, before the tension stage: finds the pairs
/// and solves each cluster of touching strings jointly (see above).
void StringPairs::couple(std::vector<StringState>& strings, RigidTable& rigids, const StepContext& ctx,
                         const std::vector<std::uint8_t>& in_island) {
    strings_ = &strings;
    pool_ = ctx.pool;
    cluster_count_ = 0;
    findPairs();
    if (string_pairs_.empty()) return;
    warmStart();
    cluster_count_ = groupClusters();
    for (std::size_t q = 0; q < cluster_count_; ++q) {
        Cluster& cl = clusters_[q];
        cl.coupled = std::any_of(cl.strings.begin(), cl.strings.end(), [&](const StringState* s) {
            const auto slot = static_cast<std::size_t>(s - strings.data());
            return slot < in_island.size() && in_island[slot];
        });
    }
    solveClusters(cluster_count_, rigids, ctx);
}

const std::vector<IslandMember*>& StringPairs::startCoupled(RigidTable& rigids, const StepContext& ctx,
                                                            std::vector<std::uint8_t>& solved) {
    coupled_.clear();
    for (std::size_t q = 0; q < cluster_count_; ++q) {
        Cluster& cl = clusters_[q];
        if (!cl.coupled || !cl.member.start(cl.strings, cl.contacts, rigids, ctx, cl.scratch)) continue;
        coupled_.push_back(&cl.member);
        for (const StringState* s : cl.strings) solved[static_cast<std::size_t>(s - strings_->data())] = 1;
    }
    return coupled_;
}

void StringPairs::finishCoupled() {
    for (std::size_t q = 0; q < cluster_count_; ++q)
        if (clusters_[q].coupled) keepForces(clusters_[q]);
}

void StringPairs::markCoupled(std::vector<std::uint8_t>& mark) const {
    for (std::size_t q = 0; q < cluster_count_; ++q)
        if (clusters_[q].coupled)
            for (const StringState* s : clusters_[q].strings) mark[static_cast<std::size_t>(s - strings_->data())] = 1;
}

void StringPairs::solveCoupledHeld(RigidTable& rigids, const StepContext& ctx) {
    for (std::size_t q = 0; q < cluster_count_; ++q) {
        Cluster& cl = clusters_[q];
        if (!cl.coupled) continue;
        // The pairs as groupClusters made them (the member's solve changed them).
        for (std::size_t i = 0; i < cl.contacts.size(); ++i) cl.contacts[i] = localContact(string_pairs_[cl.index[i]]);
        cl.scratch.always_sparse = sparse_joint_steps;
        solveStringCluster(cl.strings, cl.contacts, rigids, ctx, cl.scratch);
        keepForces(cl);
    }
}

void StringPairs::keepForces(const Cluster& cl) {
    for (std::size_t i = 0; i < cl.contacts.size(); ++i) {
        StringPairContact& c = string_pairs_[cl.index[i]];
        c.force = cl.contacts[i].force;
        c.normal = cl.contacts[i].normal;
    }
}

/// The force a pair pressed with at the end of the last step bounds its friction in the
/// first pass (both lists sorted by key).
void StringPairs::warmStart() {
    std::size_t k = 0;
    for (StringPairContact& c : string_pairs_) {
        while (k < previous_pairs_.size() && previous_pairs_[k].key() < c.key()) ++k;
        if (k < previous_pairs_.size() && previous_pairs_[k].key() == c.key()) c.force = previous_pairs_[k].force;
    }
}

/// A pair with its strings numbered within their cluster (cluster_local_).
StringPairContact StringPairs::localContact(const StringPairContact& c) const {
    StringPairContact local = c;
    local.string = cluster_local_[c.string];
    local.partner = cluster_local_[c.partner];
    return local;
}

/// Clusters: strings connected through pairs (union-find over string slots). Returns how
/// many of clusters_ this step uses.
std::size_t StringPairs::groupClusters() {
    std::vector<StringState>& strings = *strings_;
    cluster_root_.resize(strings.size());
    for (std::size_t i = 0; i < strings.size(); ++i) cluster_root_[i] = static_cast<std::uint32_t>(i);
    auto root = [&](std::uint32_t i) { return unionRoot(cluster_root_, i); };
    for (const StringPairContact& c : string_pairs_) cluster_root_[root(c.string)] = root(c.partner);
    // The pairs grouped by cluster (clusters in the order of their root slot, pairs in
    // their order within each: a counting sort by root), each cluster's strings in the
    // order its pairs name them first.
    cluster_first_.assign(strings.size() + 1, 0);
    pair_root_.resize(string_pairs_.size());
    for (std::size_t i = 0; i < string_pairs_.size(); ++i) {
        pair_root_[i] = root(string_pairs_[i].string);
        ++cluster_first_[pair_root_[i] + 1];
    }
    for (std::size_t r = 0; r < strings.size(); ++r) cluster_first_[r + 1] += cluster_first_[r];
    cluster_order_.resize(string_pairs_.size());
    cluster_fill_.assign(cluster_first_.begin(), cluster_first_.end() - 1);
    for (std::size_t i = 0; i < string_pairs_.size(); ++i) cluster_order_[cluster_fill_[pair_root_[i]]++] = i;
    cluster_local_.assign(strings.size(), ~std::uint32_t{0});
    std::size_t count = 0;
    for (std::size_t r = 0; r < strings.size(); ++r) {
        if (cluster_first_[r] == cluster_first_[r + 1]) continue;
        if (clusters_.size() <= count) clusters_.emplace_back();
        Cluster& cl = clusters_[count++];
        cl.strings.clear();
        cl.contacts.clear();
        cl.index.clear();
        cl.contacts.reserve(cluster_first_[r + 1] - cluster_first_[r]);  // not grown copy by copy
        cl.index.reserve(cluster_first_[r + 1] - cluster_first_[r]);
        for (std::size_t q = cluster_first_[r]; q < cluster_first_[r + 1]; ++q) {
            const std::size_t i = cluster_order_[q];
            const StringPairContact& c = string_pairs_[i];
            for (std::uint32_t sidx : {c.string, c.partner})
                if (cluster_local_[sidx] == ~std::uint32_t{0}) {
                    cluster_local_[sidx] = static_cast<std::uint32_t>(cl.strings.size());
                    cl.strings.push_back(&strings[sidx]);
                }
            cl.contacts.push_back(localContact(c));
            cl.index.push_back(i);
        }
    }
    return count;
}

/// Clusters share no string (and the joint solve moves no body), so they are solved on
/// the pool; each writes only its own strings and its own pairs. Those with a string in an
/// island are left to the islands (startCoupled).
void StringPairs::solveClusters(std::size_t count, RigidTable& rigids, const StepContext& ctx) {
    pool_->forEach(count, [&](std::size_t q) {
        Cluster& cl = clusters_[q];
        if (cl.coupled) return;
        cl.scratch.always_sparse = sparse_joint_steps;
        solveStringCluster(cl.strings, cl.contacts, rigids, ctx, cl.scratch);
        keepForces(cl);
    });
}

/// After the tension stage: a mass-weighted projection of the overlap the joint solve left
/// (its penalty gives way by F / k_c; usually none), moving the four ends by the fractions
/// s and t as the Strings paper does: impulse d / (w_a + w_b), w_a = (1-s)^2 w_j + s^2 w_{j+1}.
/// Then the colliding flags of the next shape matching and the next step's warm start.
void StringPairs::finish(std::vector<StringState>& strings) {
    previous_pairs_.clear();
    if (string_pairs_.empty()) return;
    auto weight = [](const StringState& s, std::size_t p) {
        return s.hold[p].kind == ParticleHold::Kind::Free ? s.inv_mass[p] : 0.0;
    };
    // The gap at the closest points now. The joint solve kept every pair on its side,
    // so the closest-point direction is the normal (the solve's where the axes touch).
    auto measure = [&](StringPairContact& c) {
        const StringState& sa = strings[c.string];
        const StringState& sb = strings[c.partner];
        const SegmentClosest cp = closestPointsOfSegments(
            sa.x[c.segment], sa.x[c.segment + 1], sb.x[c.partner_segment], sb.x[c.partner_segment + 1]);
        c.s = cp.s;
        c.partner_s = cp.t;
        const Vec3 d = cp.p - cp.q;
        if (cp.distance > kStringAxisContact * c.gap) c.normal = d / cp.distance;
        return d.dot(c.normal) - c.gap;
    };
    for (int sweep = 0; sweep < kStringCleanupSweeps; ++sweep) {
        double worst = 0.0;
        for (StringPairContact& c : string_pairs_) {
            if (strings[c.string].broken[c.segment] || strings[c.partner].broken[c.partner_segment]) continue;
            const double gap = measure(c);
            if (gap >= 0.0) continue;
            worst = std::max(worst, -gap / c.gap);
            StringState& sa = strings[c.string];
            StringState& sb = strings[c.partner];
            const double s = c.s, t = c.partner_s;
            const double a0 = (1.0 - s) * weight(sa, c.segment), a1 = s * weight(sa, c.segment + 1);
            const double b0 = (1.0 - t) * weight(sb, c.partner_segment), b1 = t * weight(sb, c.partner_segment + 1);
            const double w = (1.0 - s) * a0 + s * a1 + (1.0 - t) * b0 + t * b1;
            if (!(w > 0.0)) continue;
            const Vec3 step = (-gap / w) * c.normal;
            sa.x[c.segment] += a0 * step;
            sa.x[c.segment + 1] += a1 * step;
            sb.x[c.partner_segment] -= b0 * step;
            sb.x[c.partner_segment + 1] -= b1 * step;
        }
        if (worst <= kStringCleanupTolerance) break;
    }
    // Colliding particles weigh 3x in the next step's shape matching (Sec. 6).
    for (StringPairContact& c : string_pairs_) {
        if (c.force > 0.0) previous_pairs_.push_back(c);
        if (measure(c) > kStringTouchSlop * c.gap) continue;
        strings[c.string].colliding[c.segment] = strings[c.string].colliding[c.segment + 1] = 1;
        strings[c.partner].colliding[c.partner_segment] = strings[c.partner].colliding[c.partner_segment + 1] = 1;
    }
}

}  // namespace tearables::detail
