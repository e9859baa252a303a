// The joint strain-limit solve of strings that touch each other (string-string and self
// contacts; StringPairs gathers the clusters). The cluster's energy is the sum of the strings'
// own step energies (strain_limit.cpp) plus, per contact between segment j of string a at
// s and segment k of string b at t (b may be a),
//     k_c/2 min(0, g)^2,   g = n . (x_a(s) - x_b(t)) - (r_a + r_b),
// with x_a(s) = (1-s) x_j + s x_{j+1}, and IPC's smoothed Coulomb friction mu F f0(|u_t|)
// on the contact points' relative tangential motion u_t over the step (Li et al. 2020,
// Sec. 5; contact_rows.cpp has f0), F the normal force of the last pass (or step).
// Its Hessian is block-tridiagonal per string plus one rank-1 term per contact direction
// (the normal, two friction tangents), so a Newton step solves (A + U K U^T) dx = r by the
// Woodbury identity with the strings' own factorisations:
//     y = A^-1 r,  Z = A^-1 U,  (K^-1 + U^T Z) z = U^T y,  dx = y - Z z,
// or, for many directions, by one sparse factorisation of the whole cluster. s, t and n
// are fixed within a pass (a convex problem) and measured again between passes. Movable
// bodies are held where the strings' own solves left them (no body unknowns here).
#include "collision/capsule.hpp"
#include "string/cluster_member.hpp"
#include "string/string_island.hpp"
#include "string/strain_limit_internal.hpp"

#include <Eigen/Cholesky>
#include <Eigen/SparseCholesky>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <optional>

namespace tearables::detail {

namespace {

/// Slip of the contact points (relative, per step) below which a string contact sticks,
/// as a fraction of the thinner string's radius (the smoothing length eps of friction).
constexpr double kStringSlip = 1e-3;
/// Penalty of a string contact over the stiffest spring (or particle inertia, m / h^2) of
/// its two strings. At rope tensions it gives way by micrometres (F / k), and where a
/// contact cannot be met without stretching a string (a rope pinned back through itself)
/// it gives way as much as the rope stretches instead of stretching it without bound;
/// such a pair then starts the next step deep and is left to come apart (kStringDeepStart).
constexpr double kStringContactStiffness = 1.0;
/// Axes closer than this fraction of the thickness have no direction of their own.
constexpr double kStringAxisContact = 1e-3;
/// Another pass when a contact's closest points (fractions) or normal moved by more.
constexpr double kStringRelinearise = 1e-3;
/// Times per Newton iteration that contacts the step would hit are added and the step
/// solved again.
constexpr int kStringPredictRounds = 4;
/// Halvings of a joint Newton step before the line search takes the last one.
constexpr int kStringLineSearchHalvings = 10;
/// When a joint Newton step is solved by one sparse factorisation of the cluster's whole
/// Hessian (sparseClusterStep) instead of the Woodbury identity: past kWoodburyDirections
/// contact directions, or past kWoodburyCachedDirections when directions times particles
/// exceed kWoodburyWork. Woodbury costs a chain solve, a stored column and a dense system
/// row per direction: cheap for a few crossings, not for a long rope folded onto itself.
constexpr std::size_t kWoodburyDirections = 256;
constexpr std::size_t kWoodburyCachedDirections = 64;
constexpr std::size_t kWoodburyWork = 100000;
bool sparseStepPays(std::size_t directions, std::size_t particles) {
    return directions > kWoodburyDirections ||
           (directions > kWoodburyCachedDirections && directions * particles > kWoodburyWork);
}
/// Position accuracy of the joint solve, as a fraction of the thinnest contact.
constexpr double kStringContactTolerance = 1e-5;
/// firstTouch stops within this fraction of the gap of the touch, or after this many
/// advancements (a grazing approach; the direction there is as good).
constexpr double kStringTouchTolerance = 1e-3;
constexpr int kStringTouchIterations = 32;

/// How far a segment's real path over the step, from (p0, p1) to (q0, q1), may stray
/// from the straight one (its ends moving linearly): moved by c (its ends' larger travel)
/// while turning by theta, along an arc of that chord it strays from the chord by about
/// c theta / 8 (the sagitta).
double pathStray(const Vec3& p0, const Vec3& p1, const Vec3& q0, const Vec3& q1) {
    const Vec3 u = p1 - p0, v = q1 - q0;
    const double theta = std::atan2(u.cross(v).norm(), u.dot(v));
    const double c = std::sqrt(std::max((q0 - p0).squaredNorm(), (q1 - p1).squaredNorm()));
    return c * theta / 8.0;
}

/// Two segments moving linearly over the step, from (pa0, pa1), (pb0, pb1) at tau = 0 to
/// (a0, a1), (b0, b1) at tau = 1.
struct StraightPaths {
    Vec3 pa0, pa1, pb0, pb1, ta0, ta1, tb0, tb1;
    double r;  ///< the largest relative travel of the ends
    StraightPaths(const Vec3& pa0_, const Vec3& pa1_, const Vec3& pb0_, const Vec3& pb1_, const Vec3& a0,
                  const Vec3& a1, const Vec3& b0, const Vec3& b1)
        : pa0(pa0_), pa1(pa1_), pb0(pb0_), pb1(pb1_), ta0(a0 - pa0_), ta1(a1 - pa1_), tb0(b0 - pb0_), tb1(b1 - pb1_) {
        r = std::sqrt(std::max({(ta0 - tb0).squaredNorm(), (ta0 - tb1).squaredNorm(), (ta1 - tb0).squaredNorm(),
                                (ta1 - tb1).squaredNorm()}));
    }
    /// Where, from `tau` on, the axes first come within `reach` of each other: false when
    /// they never do; else true, with tau there and `normal` the direction from the
    /// second toward the first (the side each is on when they meet). Conservative
    /// advancement: the axes' distance changes over the step by at most r (the closest
    /// points' difference is a convex combination of the ends' differences), so advancing
    /// by (distance - reach) / r of the step never passes the first touch. Stops within
    /// kStringTouchTolerance of `scale` of the touch.
    bool firstTouch(double& tau, double reach, double scale, Vec3& normal) const {
        for (int i = 0; i < kStringTouchIterations; ++i) {
            const SegmentClosest cp =
                closestPointsOfSegments(pa0 + tau * ta0, pa1 + tau * ta1, pb0 + tau * tb0, pb1 + tau * tb1);
            const double ahead = cp.distance - reach;
            if (ahead <= kStringTouchTolerance * scale || i + 1 == kStringTouchIterations) {
                if (!(cp.distance > 0.0)) return false;
                normal = (cp.p - cp.q) / cp.distance;
                return true;
            }
            if (!(r > 0.0)) return false;
            tau += ahead / r;
            if (!(tau <= 1.0)) return false;
        }
        return false;
    }
};

/// The side on which two segments that were apart at the start of the step met during it,
/// as far as the motion tells: true when it does, with `side` the direction from the second
/// toward the first where they met and `met` whether they did. The real paths stray from
/// the straight ones by about `stray` (pathStray, summed), so the straight paths decide only
/// what every path within `stray` would: whether they met (within gap - stray: yes; never
/// within gap + stray: no), and on which side of `now` (the pair's direction at the end),
/// when the touches at gap + stray, gap - stray and gap (`side`) all see `now` on one side.
bool sideMet(const StraightPaths& path, double gap, double stray, const Vec3& now, bool& met, Vec3& side) {
    met = false;
    if (!(stray < gap)) return false;
    double tau = 0.0;
    Vec3 early, late;
    if (!path.firstTouch(tau, gap + stray, gap, early)) return true;  // never within reach
    if (!path.firstTouch(tau, gap, gap, side)) return false;
    if (!path.firstTouch(tau, gap - stray, gap, late)) return false;
    const bool behind = now.dot(side) <= 0.0;
    if ((now.dot(early) <= 0.0) != behind || (now.dot(late) <= 0.0) != behind) return false;
    met = true;
    return true;
}

/// A factorised chain system for many solves: the block Thomas factorisation of
/// factorBlockTridiagonal with the pivots inverted once (a solve is then mat-vecs only),
/// and a forward sweep that starts at the first nonzero of the right-hand side.
struct ChainSolver {
    std::vector<Mat3> inverse;  // D'_i^-1
    std::vector<char> coupled;  // gain_i != 0
    void factor(StringState& s) {
        factorChain(s);
        const std::size_t n = s.particles();
        inverse.resize(n);
        coupled.resize(n);
        for (std::size_t i = 0; i < n; ++i) {
            inverse[i] = s.scratch.blk_factor[i].solve(Mat3(Mat3::Identity()));
            coupled[i] = s.scratch.blk_coupled[i];
        }
    }
    void solve(const StringState& s, std::vector<Vec3>& rhs, std::size_t first = 0) const {
        const std::size_t n = s.particles();
        for (std::size_t i = std::max<std::size_t>(first, 1); i < n; ++i)
            if (coupled[i]) rhs[i] -= s.scratch.blk_factor_gain[i] * rhs[i - 1];
        rhs[n - 1] = inverse[n - 1] * rhs[n - 1];
        for (std::size_t i = n - 1; i-- > 0;) rhs[i] = inverse[i] * (rhs[i] - s.scratch.blk_off[i] * rhs[i + 1]);
    }
};

}  // namespace

namespace cluster {

/// One entry of a contact direction's gradient u: coefficient of a particle's motion.
/// `held`: a particle glued to a body of an island, which moves with the body (in an
/// island's cluster only: elsewhere a held particle has no entry).
struct UEntry {
    std::uint32_t string;
    std::size_t particle;
    Vec3 coef;
    bool held = false;
};

/// A rank-1 term of the joint Hessian (a contact's normal, or a friction tangent).
struct Direction {
    UEntry u[4];
    int entries = 0;
    double weight = 0.0;             // its Hessian weight (k_c or the friction's)
    /// A contact held where the step runs into it (predictContacts): its gap now where the
    /// model's k_c (g + u^T dx)^2 / 2 carries it (gradient k_c g u); 0 for the others.
    double gap = 0.0;
    bool off = false;                 // let go again: not in the step
    std::size_t column[2] = {0, 0};  // offsets of Z in `pool` for its strings
    std::uint32_t string[2] = {0, 0};
    int strings = 0;
};

}  // namespace cluster

/// What solveStringCluster needs besides the strings, kept between calls so that a
/// running step does not allocate (vectors only grow).
struct ClusterScratch::Impl {
    std::vector<double> stiffest;
    std::vector<char> shadowed, was_shadowed, forward;
    std::vector<char> predicted;             // per contact: held as one the step runs into
    std::vector<std::size_t> predicted_dir;  // per contact: its direction in `dirs` while predicted
    std::vector<char> touches;               // per string: touches another (chooseStart)
    std::vector<std::vector<Vec3>> own;      // per string: where its own solve ended
    std::vector<std::pair<PairKey, std::size_t>> keys;  // unordered keys with their contacts, sorted
    std::vector<double> friction_bound;  // per contact: mu F of the pass
    std::vector<std::size_t> live, candidates, on;
    std::vector<double> gap_seen, travel_seen;
    std::vector<cluster::Direction> dirs;
    std::vector<Vec3> pool, column;
    std::vector<ChainSolver> solvers;
    std::vector<std::vector<Vec3>> y;
    /// The Woodbury system of `dim` contact directions and its factorisation, one set per
    /// dim up to kCachedDims, each allocated with the sets up to twice it when its size first
    /// occurs (Eigen's dynamic matrices reallocate on any resize): a running scene steps
    /// without allocating. Larger systems share one set, allocating.
    struct Woodbury {
        Eigen::MatrixXd sys;
        Eigen::VectorXd rhs, z;
        Eigen::LDLT<Eigen::MatrixXd> ldlt;
    };
    /// Each string's right-hand side of the Newton system, for sparseClusterStep (the
    /// Woodbury step overwrites blk_rhs); and that step's matrix and factorisation.
    std::vector<std::vector<Vec3>> r;
    std::vector<Eigen::Triplet<double>> triplets;
    Eigen::SparseMatrix<double> hessian;
    Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> sparse;
    Eigen::VectorXd sparse_rhs, sparse_dx;
    static constexpr auto kCachedDims = static_cast<Eigen::Index>(kWoodburyCachedDirections);
    std::vector<std::unique_ptr<Woodbury>> by_dim;  ///< [dim], or [0] for dims past kCachedDims
    Woodbury& woodbury(Eigen::Index dim) {
        if (by_dim.empty()) by_dim.resize(static_cast<std::size_t>(kCachedDims) + 1);
        if (dim > kCachedDims) {
            if (!by_dim[0]) by_dim[0] = std::make_unique<Woodbury>();
            return *by_dim[0];
        }
        if (!by_dim[static_cast<std::size_t>(dim)])
            for (Eigen::Index k = 1; k <= std::min(2 * dim, kCachedDims); ++k) {
                std::unique_ptr<Woodbury>& set = by_dim[static_cast<std::size_t>(k)];
                if (set) continue;
                set = std::make_unique<Woodbury>();
                set->sys.setIdentity(k, k);
                set->rhs.setZero(k);
                set->z.setZero(k);
                set->ldlt.compute(set->sys);
            }
        return *by_dim[static_cast<std::size_t>(dim)];
    }
};

namespace {

/// The joint Newton step of many contact directions, (A + U W U^T) dx = r (A the strings'
/// block-tridiagonal systems as assembled, fixed rows identity; r in sc.r), as one sparse
/// symmetric matrix of the cluster's 3n unknowns, factorised by SimplicialLDLT (AMD): the
/// Woodbury step to rounding. dx into the strings' blk_rhs (zero where not free); false,
/// blk_rhs untouched, if the factorisation fails or the step is not finite. It allocates;
/// it runs for the large clusters of sparseStepPays, or where a test asks for it.
bool sparseClusterStep(const std::vector<StringState*>& strings, const std::vector<cluster::Direction>& dirs,
                       ClusterScratch::Impl& sc) {
    std::vector<Eigen::Index> offset(strings.size() + 1, 0);
    for (std::size_t i = 0; i < strings.size(); ++i)
        offset[i + 1] = offset[i] + 3 * static_cast<Eigen::Index>(strings[i]->particles());
    auto add = [&](Eigen::Index row, Eigen::Index col, const Mat3& block) {
        for (Eigen::Index a = 0; a < 3; ++a)
            for (Eigen::Index b = 0; b < 3; ++b)
                if (block(a, b) != 0.0 && row + a >= col + b) sc.triplets.emplace_back(row + a, col + b, block(a, b));
    };
    sc.triplets.clear();
    for (std::size_t i = 0; i < strings.size(); ++i) {
        const StringState& s = *strings[i];
        for (std::size_t p = 0; p < s.particles(); ++p) {
            const Eigen::Index row = offset[i] + 3 * static_cast<Eigen::Index>(p);
            add(row, row, s.scratch.blk_diag[p]);
            if (p + 1 < s.particles()) add(row + 3, row, s.scratch.blk_off[p].transpose());  // A(p+1, p)
        }
    }
    // A direction's term w u u^T: its entries pairwise (the lower triangle is read).
    for (const cluster::Direction& d : dirs)
        for (int a = 0; a < d.entries && !d.off; ++a)
            for (int b = 0; b < d.entries; ++b) {
                const Eigen::Index row = offset[d.u[a].string] + 3 * static_cast<Eigen::Index>(d.u[a].particle);
                const Eigen::Index col = offset[d.u[b].string] + 3 * static_cast<Eigen::Index>(d.u[b].particle);
                if (row >= col) add(row, col, d.weight * d.u[a].coef * d.u[b].coef.transpose());
            }
    const Eigen::Index dim = offset.back();
    sc.hessian.resize(dim, dim);
    sc.hessian.setFromTriplets(sc.triplets.begin(), sc.triplets.end());  // sums duplicates
    sc.sparse.compute(sc.hessian);
    if (sc.sparse.info() != Eigen::Success) return false;
    sc.sparse_rhs.resize(dim);
    for (std::size_t i = 0; i < strings.size(); ++i)
        for (std::size_t p = 0; p < strings[i]->particles(); ++p)
            sc.sparse_rhs.segment<3>(offset[i] + 3 * static_cast<Eigen::Index>(p)) = sc.r[i][p];
    for (const cluster::Direction& d : dirs)
        for (int a = 0; a < d.entries && !d.off && d.gap != 0.0; ++a)
            sc.sparse_rhs.segment<3>(offset[d.u[a].string] + 3 * static_cast<Eigen::Index>(d.u[a].particle)) -=
                d.weight * d.gap * d.u[a].coef;
    sc.sparse_dx = sc.sparse.solve(sc.sparse_rhs);
    if (sc.sparse.info() != Eigen::Success || !sc.sparse_dx.allFinite()) return false;
    for (std::size_t i = 0; i < strings.size(); ++i) {
        StringState& s = *strings[i];
        for (std::size_t p = 0; p < s.particles(); ++p)
            s.scratch.blk_rhs[p] = freeParticle(s, p)
                                       ? Vec3(sc.sparse_dx.segment<3>(offset[i] + 3 * static_cast<Eigen::Index>(p)))
                                       : Vec3::Zero();
    }
    return true;
}

}  // namespace

ClusterScratch::ClusterScratch() : impl(std::make_unique<Impl>()) {}
ClusterScratch::~ClusterScratch() = default;
ClusterScratch::ClusterScratch(ClusterScratch&&) noexcept = default;
ClusterScratch& ClusterScratch::operator=(ClusterScratch&&) noexcept = default;

namespace {

using cluster::Direction;
using cluster::UEntry;

/// The joint Newton solve of one cluster (see the file's header): passes of Newton
/// iterations with the contacts' closest points, normals and friction weights fixed, each
/// iteration assembling the strings' own systems and the contacts' rows (assemble),
/// factorising the strings (factor), solving the joint step by the Woodbury identity or
/// one sparse factorisation (jointStep), adding the contacts the step would run into
/// (addPredictedContacts) and moving along it by a line search (lineSearch); between
/// passes the contacts are measured again (endPass). Its scratch is the caller's
/// ClusterScratch.
class ClusterSolver {
public:
    ClusterSolver(const std::vector<StringState*>& strings, std::vector<StringPairContact>& contacts, RigidTable& rigids,
                  const StepContext& ctx, ClusterScratch& work)
        : strings_(strings), contacts_(contacts), rigids_(rigids), ctx_(ctx), work_(work), sc_(*work.impl),
          count_(strings.size()), inv_h2_(ctx.inv_h * ctx.inv_h) {}

    void solve() {
        if (!setup()) return;
        const int iterations = ctx_.settings->strain_iterations * kContactIterationFactor;
        for (int pass = 0; pass < kContactPasses; ++pass) {
            bool converged = false;
            beginPass();
            for (int iter = 0; iter < iterations; ++iter) {
                newtonStep();
                if (lineSearch()) {
                    converged = true;
                    break;
                }
            }
            if (!endPass() && converged) break;
        }
        finish();
    }

    // --- as a member of an island (ClusterIslandMember) -----------------------------------
    // The strings' systems are their island members' (the bodies' unknowns condensed out of
    // them) and the step is the island's; this solver gives the contacts' terms, directions
    // and columns of Z, their energy, predicted set and passes.

    /// The contacts' geometry and weights where the strings are (no choice of start: the
    /// island's strings are where it left them); false where no pair touches.
    bool startInIsland() {
        island_ = true;
        return setup(false);
    }
    void beginIslandPass() { beginPass(); }
    /// After the members assembled the strings' systems: the contacts' gradients, and the
    /// held contacts' gaps (their model's k_c (g + u^T dx)^2 / 2: gradient k_c g u), into
    /// blk_rhs. The columns of Z are then to be solved again (islandColumns).
    void addIslandTerms(bool fresh) {
        held_rhs_.resize(count_);
        for (std::size_t i = 0; i < count_; ++i) held_rhs_[i].assign(strings_[i]->particles(), Vec3::Zero());
        addContactTerms(fresh);
        for (const Direction& d : sc_.dirs)
            if (!d.off && d.gap != 0.0)
                for (int e = 0; e < d.entries; ++e) addRhs(d.u[e], -d.weight * d.gap * d.u[e].coef);
        sc_.pool.clear();
        solved_ = 0;
    }
    /// The contacts' gradient at the glued particles of string i (addIslandTerms).
    const std::vector<Vec3>& heldRhs(std::size_t i) const { return held_rhs_[i]; }
    /// Z = A^-1 U for every direction, through the chains' factorisations (the members').
    void islandColumns() { columns(); }
    const std::vector<Direction>& directions() const { return sc_.dirs; }
    Vec3 column(const Direction& d, std::uint32_t string, std::size_t p) const { return zAt(d, string, p); }
    void subtractIslandColumn(const Direction& d, double f) { subtractColumn(d, f); }
    StringState& string(std::size_t i) const { return *strings_[i]; }
    /// The island's step is in blk_rhs: the contacts it can reach.
    void islandStepKnown() { findCandidates(stepReach()); }
    bool predictIslandContacts() { return predictContacts(); }
    double contactEnergy(double alpha) const {
        double e = 0.0;
        for (std::size_t ci : sc_.candidates) addContactEnergy(ci, alpha, e);
        return e;
    }
    /// Before the strings take alpha of the step: the travel that bounds the contacts' gaps.
    void islandMoves(double alpha) {
        double worst = 0.0;
        for (const StringState* sp : strings_)
            for (std::size_t p = 0; p < sp->particles(); ++p) {
                const Vec3 dx = alpha * stepOf(*sp, p);
                if (dx.allFinite()) worst = std::max(worst, dx.norm());
            }
        travel_ += 2.0 * worst;
    }
    bool endIslandPass() { return endPass(); }
    /// After the members finished their strings (finishChain).
    void finishInIsland() { pressRows(); }

private:
    // --- the contacts' geometry ---------------------------------------------------------

    /// Positions along the current Newton step (held in blk_rhs; a glued particle's, in an
    /// island, in held_step), alpha of the way.
    static Vec3 at(const StringState& s, std::size_t p, double alpha) {
        if (freeParticle(s, p)) return s.x[p] + alpha * s.scratch.blk_rhs[p];
        return s.scratch.held_step.empty() ? s.x[p] : Vec3(s.x[p] + alpha * s.scratch.held_step[p]);
    }
    /// The whole step's move of particle p (at(s, p, 1) - x).
    static Vec3 stepOf(const StringState& s, std::size_t p) {
        if (freeParticle(s, p)) return s.scratch.blk_rhs[p];
        return s.scratch.held_step.empty() ? Vec3::Zero() : s.scratch.held_step[p];
    }
    /// A particle that moves with a body of the island (an entry of its own, `held`).
    bool moves(const StringState& s, std::size_t p) const { return island_ && s.glue_movable[p]; }
    static Vec3 sidePoint(const StringState& s, std::size_t j, double f, double alpha) {
        return Vec3((1.0 - f) * at(s, j, alpha) + f * at(s, j + 1, alpha));
    }
    static Vec3 startPoint(const StringState& s, std::size_t j, double f) {
        return Vec3((1.0 - f) * s.x_prev[j] + f * s.x_prev[j + 1]);
    }
    double gapAt(const StringPairContact& c, double alpha) const {
        const Vec3 pa = sidePoint(*strings_[c.string], c.segment, c.s, alpha);
        const Vec3 pb = sidePoint(*strings_[c.partner], c.partner_segment, c.partner_s, alpha);
        return c.normal.dot(pa - pb) - c.gap;
    }
    /// Relative tangential motion of the contact points over the step.
    Vec3 slipAt(const StringPairContact& c, double alpha) const {
        const StringState& a = *strings_[c.string];
        const StringState& b = *strings_[c.partner];
        Vec3 rel = (sidePoint(a, c.segment, c.s, alpha) - startPoint(a, c.segment, c.s)) -
                   (sidePoint(b, c.partner_segment, c.partner_s, alpha) - startPoint(b, c.partner_segment, c.partner_s));
        return Vec3(rel - c.normal * c.normal.dot(rel));
    }
    /// The (up to four) particle entries of a contact direction e: +e at this side's ends by
    /// the fractions, -e at the other side's.
    int entries(const StringPairContact& c, const Vec3& e, UEntry* out) const {
        int k = 0;
        const StringState& a = *strings_[c.string];
        const StringState& b = *strings_[c.partner];
        auto add = [&](std::uint32_t string, const StringState& s, std::size_t p, const Vec3& coef) {
            if (freeParticle(s, p)) {
                out[k++] = {string, p, coef, false};
            } else if (moves(s, p)) {
                out[k++] = {string, p, coef, true};
            }
        };
        add(c.string, a, c.segment, (1.0 - c.s) * e);
        add(c.string, a, c.segment + 1, c.s * e);
        add(c.partner, b, c.partner_segment, -(1.0 - c.partner_s) * e);
        add(c.partner, b, c.partner_segment + 1, -c.partner_s * e);
        return k;
    }
    /// Adds v to the right-hand side at entry e's particle (a held one's: held_rhs, which
    /// the island's member gives the particle's body).
    void addRhs(const UEntry& e, const Vec3& v) {
        if (e.held) {
            held_rhs_[e.string][e.particle] += v;
        } else {
            strings_[e.string]->scratch.blk_rhs[e.particle] += v;
        }
    }

    /// Closest points and normal at the given positions: the predicted ones in the first
    /// pass (the strings' own solves may have pulled one through the other), the current
    /// ones later. The contact takes the closest-point direction, free to turn while the
    /// pair comes into reach, unless the positions carried the pair through itself: then the
    /// side it was on, from the motion since the start (a pair touching at the start: its
    /// start normal; one that came into reach: sideMet; where the straight paths do not tell,
    /// e.g. a torn rope whipping round its pin, only axes that crossed: a flipped perpendicular).
    void linearise(StringPairContact& c, bool predicted) {
        // Where a particle is for this: its prediction, unless a huge force sent that past
        // where max_speed reaches in a step (then where its own solve left it).
        const double reach2 = ctx_.settings->max_speed * ctx_.h * ctx_.settings->max_speed * ctx_.h;
        auto where = [reach2, predicted](const StringState& s, std::size_t p) -> const Vec3& {
            return predicted && (s.x_pred[p] - s.x_prev[p]).squaredNorm() <= reach2 ? s.x_pred[p] : s.x[p];
        };
        const StringState& a = *strings_[c.string];
        const StringState& b = *strings_[c.partner];
        const std::size_t j = c.segment, k = c.partner_segment;
        const Vec3 a0 = where(a, j), a1 = where(a, j + 1), b0 = where(b, k), b1 = where(b, k + 1);
        const Vec3 pa0 = a.x_prev[j], pa1 = a.x_prev[j + 1], pb0 = b.x_prev[k], pb1 = b.x_prev[k + 1];
        const SegmentClosest cp = closestPointsOfSegments(a0, a1, b0, b1);
        c.s = cp.s;
        c.partner_s = cp.t;
        const Vec3 d = cp.p - cp.q;
        Vec3 side = c.start_normal;
        bool crossed = false;
        if (c.start_distance < c.gap * (1.0 + kContactSlop)) {
            crossed = d.dot(side) <= 0.0;
        } else if (sideMet(StraightPaths(pa0, pa1, pb0, pb1, a0, a1, b0, b1), c.gap,
                           pathStray(pa0, pa1, a0, a1) + pathStray(pb0, pb1, b0, b1), d, crossed, side)) {
            crossed = crossed && d.dot(side) <= 0.0;
        } else if (predicted && cp.distance < c.gap && cp.s > 0.0 && cp.s < 1.0 && cp.t > 0.0 && cp.t < 1.0) {
            const Vec3 m = (a1 - a0).cross(b1 - b0);
            const Vec3 m0 = (pa1 - pa0).cross(pb1 - pb0);
            crossed = m.dot(m0) > 0.0 && m.dot(a0 - b0) * m0.dot(pa0 - pb0) < 0.0;
        }
        if (cp.distance > kStringAxisContact * c.gap && !crossed)
            c.normal = d / cp.distance;
        else if (predicted || crossed)
            c.normal = side;  // else: keep the last pass's normal
    }

    // --- shadowed contacts ----------------------------------------------------------------
    // A contact whose closest point is the far end of a segment, shared with the next
    // segment that has a contact with the same other segment, is implied by that one (the
    // shared particle lies on both): it is shadowed, so that the four pairs of two strings
    // crossing at particles do not push four times and toggle against each other.

    /// The contacts' keys, sorted for the binary searches of `find`.
    void sortKeys() {
        sc_.keys.resize(contacts_.size());
        for (std::size_t i = 0; i < contacts_.size(); ++i) sc_.keys[i] = {contacts_[i].key().unordered(), i};
        std::sort(sc_.keys.begin(), sc_.keys.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
    }
    /// The contact of segment ja of string sa with segment jb of string sb, if the step has
    /// it and neither segment is broken.
    const StringPairContact* find(std::uint32_t sa, std::int64_t ja, std::uint32_t sb, std::int64_t jb) const {
        if (ja < 0 || jb < 0 || ja >= static_cast<std::int64_t>(strings_[sa]->segments()) ||
            jb >= static_cast<std::int64_t>(strings_[sb]->segments()) || strings_[sa]->broken[static_cast<std::size_t>(ja)] ||
            strings_[sb]->broken[static_cast<std::size_t>(jb)])
            return nullptr;
        const PairKey k = PairKey{sa, static_cast<std::uint32_t>(ja), sb, static_cast<std::uint32_t>(jb)}.unordered();
        const auto it = std::lower_bound(sc_.keys.begin(), sc_.keys.end(), k, [](const auto& e, const PairKey& key) { return e.first < key; });
        return it != sc_.keys.end() && it->first == k ? &contacts_[it->second] : nullptr;
    }
    bool exists(std::uint32_t sa, std::int64_t ja, std::uint32_t sb, std::int64_t jb) const { return find(sa, ja, sb, jb) != nullptr; }
    /// The rule above; then a contact whose closest point is an end of a segment (s or t
    /// 0 or 1) that the pair of the neighbouring segment through that end touches more
    /// deeply (a smaller gap, the pair not shadowed by the rule above) is shadowed too: its
    /// distance, at the joint, is no less than the deeper pair's (the joint is a point of
    /// both segments), so it adds no contact the capsules have, only a push along its own
    /// normal, tilted toward the joint. A rope wrapped round a pinned rope of segments shorter than its
    /// own had such a pair at every chord, pushing it along the other's axis: it walked
    /// off and slid 0.07-9 m where it should have held. (Edges toward deeper pairs only,
    /// to pairs the first rule left: no cycle of shadows can leave a touching point bare.)
    /// Between two strings only: a string's contacts with itself keep the first rule (with
    /// both, the telephone cord coiled by less than 1 turn of writhe instead of more than 2:
    /// not traced).
    void shadow() {
        for (std::size_t i = 0; i < contacts_.size(); ++i) {
            const StringPairContact& c = contacts_[i];
            const std::int64_t j = c.segment, k = c.partner_segment;
            // Toward the next segment only, so that two pairs never shadow each other.
            sc_.shadowed[i] = (c.s == 1.0 && exists(c.string, j + 1, c.partner, k)) ||
                              (c.partner_s == 1.0 && exists(c.string, j, c.partner, k + 1));
        }
        sc_.forward = sc_.shadowed;
        for (std::size_t i = 0; i < contacts_.size(); ++i) {
            const StringPairContact& c = contacts_[i];
            if (sc_.forward[i] || c.string == c.partner) continue;
            const std::int64_t j = c.segment, k = c.partner_segment;
            const double g = gapAt(c, 0.0);
            const StringPairContact* n[4] = {
                c.s == 0.0 ? find(c.string, j - 1, c.partner, k) : nullptr, c.s == 1.0 ? find(c.string, j + 1, c.partner, k) : nullptr,
                c.partner_s == 0.0 ? find(c.string, j, c.partner, k - 1) : nullptr,
                c.partner_s == 1.0 ? find(c.string, j, c.partner, k + 1) : nullptr};
            for (const StringPairContact* p : n)
                if (p && !sc_.forward[static_cast<std::size_t>(p - contacts_.data())] && gapAt(*p, 0.0) < g) sc_.shadowed[i] = 1;
        }
    }
    bool skipped(const StringPairContact& c) const {
        return sc_.shadowed[static_cast<std::size_t>(&c - contacts_.data())] || strings_[c.string]->broken[c.segment] ||
               strings_[c.partner]->broken[c.partner_segment];
    }

    // --- friction ---------------------------------------------------------------------------

    /// Whether the two segments are within touching distance now. A pair found on the swept
    /// segments of a string flung at max_speed has a normal and closest points from its
    /// prediction that say nothing of where it is, and its penalty's force may be spurious:
    /// friction needs the strings to touch (a torn piece flung past a rope 0.7 m away
    /// dragged it 5 cm).
    bool near(const StringPairContact& c) const {
        const StringState& a = *strings_[c.string];
        const StringState& b = *strings_[c.partner];
        return closestPointsOfSegments(a.x[c.segment], a.x[c.segment + 1], b.x[c.partner_segment], b.x[c.partner_segment + 1]).distance <
               c.gap * (1.0 + kContactSlop);
    }
    /// Friction acts where the last pass (or step) found a pressing force.
    bool frictional(const StringPairContact& c) const { return c.friction > 0.0 && c.force > 0.0 && !skipped(c); }
    /// The slip a step below which a contact sticks (friction's smoothing eps), relative
    /// to the thinner string: under a load that friction holds a contact creeps by up to
    /// eps a step (a thin rope on a thick one crept 4 mm/s with eps of the sum of the radii).
    double slipSmoothing(const StringPairContact& c) const {
        return kStringSlip * std::min(strings_[c.string]->radius[c.segment], strings_[c.partner]->radius[c.partner_segment]);
    }
    /// Friction of a pass: D = mu F f0(|u_t|), F fixed within the pass: convex in the
    /// positions (f0 convex and increasing, of the norm of a linear function), so Newton
    /// decides stick and slip by minimising it: Coulomb's mu F against a slide, a stiff
    /// spring (2 mu F / eps at rest) below eps of slip.
    double frictionEnergy(std::size_t i, double alpha) const {
        const StringPairContact& c = contacts_[i];
        return sc_.friction_bound[i] * mollify(slipAt(c, alpha).norm(), slipSmoothing(c)).f0;
    }
    /// Each contact's mu F for the next pass. Returns how far the last pass's friction
    /// missed Coulomb's law with these forces: the largest coulombMiss of a contact.
    double weighFriction() {
        double largest = 0.0;
        for (const StringPairContact& c : contacts_)
            if (frictional(c)) largest = std::max(largest, c.friction * c.force);
        double change = 0.0;
        for (std::size_t i = 0; i < contacts_.size(); ++i) {
            const StringPairContact& c = contacts_[i];
            const double bound = frictional(c) && near(c) ? c.friction * c.force : 0.0;
            const double slip = slipAt(c, 0.0).norm(), eps = slipSmoothing(c);
            const double applied = sc_.friction_bound[i] * mollify(slip, eps).f1_over_y * slip;
            change = std::max(change, coulombMiss(applied, bound, slip, eps, largest));
            sc_.friction_bound[i] = bound;
        }
        return change;
    }

    // --- contacts known to stay apart ---------------------------------------------------
    // Each contact keeps a lower bound of its gap: the gap last computed, less twice the
    // largest particle move since (`travel_`; a contact point is a convex combination of two
    // particles and the normal is unit). A contact whose bound clears what a step can close
    // stays apart and is left out of the loops (the same sums). `live`: the contacts not
    // skipped in this pass; `candidates`: those a step of `reach` could bring to touch, or
    // with friction, in order.

    bool clear(std::size_t ci, double reach) const {
        return sc_.gap_seen[ci] - (travel_ - sc_.travel_seen[ci]) > reach * (1.0 + 1e-6) + 1e-6 * contacts_[ci].gap;
    }
    double seeGap(std::size_t ci) {
        sc_.gap_seen[ci] = gapAt(contacts_[ci], 0.0);
        sc_.travel_seen[ci] = travel_;
        return sc_.gap_seen[ci];
    }
    /// Twice the largest move of the step held in blk_rhs (infinite if any is not finite,
    /// so that nothing is left out).
    double stepReach() const {
        double largest = 0.0;
        for (const StringState* sp : strings_)
            for (std::size_t p = 0; p < sp->particles(); ++p) {
                const double d = stepOf(*sp, p).squaredNorm();
                largest = std::isfinite(d) ? std::max(largest, d) : std::numeric_limits<double>::infinity();
            }
        return 2.0 * std::sqrt(largest);
    }
    void findCandidates(double reach) {
        sc_.candidates.clear();
        for (std::size_t ci : sc_.live)
            if (!clear(ci, reach) || sc_.friction_bound[ci] > 0.0) sc_.candidates.push_back(ci);
    }

    // --- the stages -------------------------------------------------------------------------

    /// Planes, tolerance, penalties, the contacts' first closest points and normals, and
    /// friction weights. False where the strings' own solves already keep every pair apart
    /// (and no pair pressed at the end of the last step): that state is the joint optimum.
    bool setup(bool choose_start = true) {
        // The rigid contacts' planes where the bodies are now (other strings' solves may
        // have moved them since this string's own); the bodies stay there in this solve.
        for (StringState* s : strings_) linearisePlanes(*s, rigids_);
        double shortest = 1e300;
        for (const StringState* s : strings_) shortest = std::min(shortest, s->shortest_rest);
        // Converged when no particle moves by more than the strain tolerance of the
        // shortest segment or kStringContactTolerance of the thinnest contact, whichever is
        // larger (the taut-but-slack segments of assembleChain make Newton linear near the end).
        double thinnest = 1e300;
        for (const StringPairContact& c : contacts_) thinnest = std::min(thinnest, c.gap);
        tol_ = std::max(ctx_.settings->strain_tolerance * shortest, kStringContactTolerance * thinnest);

        // Penalty of a contact: the stiffest spring or particle inertia of either side.
        std::vector<double>& stiffest = sc_.stiffest;
        stiffest.assign(count_, 0.0);
        for (std::size_t i = 0; i < count_; ++i) stiffest[i] = stiffestTerm(*strings_[i], inv_h2_);
        for (StringPairContact& c : contacts_)
            c.stiffness = kStringContactStiffness * std::max(stiffest[c.string], stiffest[c.partner]);

        sc_.shadowed.assign(contacts_.size(), 0);
        sc_.predicted.assign(contacts_.size(), 0);
        sc_.predicted_dir.assign(contacts_.size(), 0);
        sortKeys();
        for (StringPairContact& c : contacts_) linearise(c, true);
        shadow();
        for (StringPairContact& c : contacts_) c.active = !skipped(c) && gapAt(c, 0.0) < 0.0;
        sc_.friction_bound.assign(contacts_.size(), 0.0);
        weighFriction();
        bool touching = false;
        for (std::size_t i = 0; i < contacts_.size(); ++i)
            touching = touching || contacts_[i].active || sc_.friction_bound[i] > 0.0;
        if (!touching) return false;
        if (choose_start) chooseStart();

        if (sc_.solvers.size() < count_) {
            sc_.solvers.resize(count_);
            sc_.y.resize(count_);
        }
        sc_.gap_seen.resize(contacts_.size());
        sc_.travel_seen.resize(contacts_.size());
        travel_ = 0.0;
        for (const StringState* sp : strings_) cluster_particles_ += sp->particles();
        return true;
    }

    /// Where the solve starts: where the strings' own solves ended, or, for the strings that
    /// touch another string, where they started (their prediction), whichever the
    /// cluster's energy is lower at (the energy is convex in the positions: either start
    /// has the same minimum). Each own solve ignored the other strings, so a rope pulled taut round
    /// another one ended its own solve millimetres inside it, and the joint solve, starting
    /// there with its contacts linearised at the prediction, pushed it out along a path of
    /// its own: a zigzag of alternate particles 0.2 mm deep that flipped every step, whose
    /// slip spent the friction (a rope wrapped a full turn slid at 0.95 of e^(mu theta)).
    /// A prediction that a huge force sent past max_speed is no start.
    void chooseStart() {
        const double reach = ctx_.settings->max_speed * ctx_.h;
        std::vector<char>& touches = sc_.touches;
        touches.assign(count_, 0);
        for (std::size_t i = 0; i < contacts_.size(); ++i)
            if ((contacts_[i].active || sc_.friction_bound[i] > 0.0) && contacts_[i].string != contacts_[i].partner)
                touches[contacts_[i].string] = touches[contacts_[i].partner] = 1;
        for (StringState* sp : strings_) std::fill(sp->scratch.blk_rhs.begin(), sp->scratch.blk_rhs.end(), Vec3::Zero());
        const double own_energy = startEnergy();
        if (sc_.own.size() < count_) sc_.own.resize(count_);
        for (std::size_t i = 0; i < count_; ++i) {
            if (!touches[i]) continue;
            StringState& s = *strings_[i];
            sc_.own[i] = s.x;
            for (std::size_t p = 0; p < s.particles(); ++p)
                if (freeParticle(s, p) && (s.x_pred[p] - s.x_prev[p]).squaredNorm() <= reach * reach) s.x[p] = s.x_pred[p];
        }
        if (!(startEnergy() < own_energy))
            for (std::size_t i = 0; i < count_; ++i)
                if (touches[i]) strings_[i]->x = sc_.own[i];
        for (StringPairContact& c : contacts_) c.active = !skipped(c) && gapAt(c, 0.0) < 0.0;
    }

    /// The cluster's energy where the strings are (every contact not skipped).
    double startEnergy() const {
        double e = 0.0;
        for (const StringState* s : strings_) e += stepEnergy(*s, rigids_, ctx_, 0.0);
        for (std::size_t ci = 0; ci < contacts_.size(); ++ci)
            if (!skipped(contacts_[ci])) addContactEnergy(ci, 0.0, e);
        return e;
    }

    /// The live contacts of a pass, their gaps not known yet.
    void beginPass() {
        plain_next_ = false;
        sc_.live.clear();
        for (std::size_t ci = 0; ci < contacts_.size(); ++ci) {
            if (skipped(contacts_[ci])) {
                contacts_[ci].active = false;
                continue;
            }
            sc_.live.push_back(ci);
            sc_.gap_seen[ci] = -std::numeric_limits<double>::infinity();
            sc_.travel_seen[ci] = 0.0;
        }
        travel_ = 0.0;
    }

    /// Each string's own system (glued particles held: no body unknowns here), then the
    /// contacts' gradients into the strings' right-hand sides and their Hessians' rank-1
    /// directions into `dirs` (addContactTerms).
    void assemble() {
        for (StringState* sp : strings_) {
            StringState& s = *sp;
            assembleChain(s, rigids_, ctx_, nullptr);
            assembleRigidContacts(s);
            for (std::size_t p = 0; p < s.particles(); ++p) {
                if (freeParticle(s, p)) continue;
                s.scratch.blk_diag[p] = Mat3::Identity();
                s.scratch.blk_rhs[p].setZero();
                if (p > 0) s.scratch.blk_off[p - 1].setZero();
                if (p < s.segments()) s.scratch.blk_off[p].setZero();
            }
            for (auto& step : s.scratch.node_step) step.setZero();
        }
        addContactTerms(true);
    }

    /// The contacts' gradients into the strings' right-hand sides; with `fresh`, their
    /// active set (the contacts that penetrate now) and their Hessians' rank-1 directions
    /// into `dirs` (else the set and directions of the last fresh call, the state unmoved
    /// since: an island's member assembles its strings again within one iteration).
    void addContactTerms(bool fresh) {
        std::vector<Direction>& dirs = sc_.dirs;
        if (fresh) dirs.clear();
        for (std::size_t ci : sc_.live) {
            StringPairContact& c = contacts_[ci];
            // The penalty k_c/2 min(0, g)^2 is one-sided: it never pulls, so a normal that
            // turned at a corner cannot drag the strings together. (A contact held since
            // the fresh call, predictContacts, has its term in its direction, with its gap.)
            const double g = !fresh ? (c.active && !sc_.predicted[ci] ? gapAt(c, 0.0) : 1.0) : clear(ci, 0.0) ? 1.0 : seeGap(ci);
            if (fresh) {
                sc_.predicted[ci] = 0;
                c.active = g < 0.0;
            }
            if (g < 0.0) {
                // Normal: gradient k g u, Hessian k u u^T.
                UEntry u[4];
                const int k = entries(c, c.normal, u);
                for (int i = 0; i < k; ++i) addRhs(u[i], -c.stiffness * g * u[i].coef);
                Direction dn;
                dn.entries = entries(c, c.normal, dn.u);
                dn.weight = c.stiffness;
                if (fresh && dn.entries > 0) dirs.push_back(dn);
            }
            const double bound = sc_.friction_bound[ci];
            if (!(bound > 0.0)) continue;
            // Friction D = mu F f0(|u_t|): gradient mu F f1(y) / y u_t on the relative
            // motion (y = |u_t|), Hessian on the tangent plane mu F f1'(y) along the slip and
            // mu F f1(y) / y across it (both >= 0; at rest 2 mu F / eps either way).
            const Vec3 slip = slipAt(c, 0.0);
            const double y = slip.norm();
            const Mollifier m = mollify(y, slipSmoothing(c));
            const Vec3 grad = (bound * m.f1_over_y) * slip;
            // d(rel)/dx has the same entries as the gradient of g with e = I.
            UEntry ug[4];
            const int kg = entries(c, Vec3::Ones(), ug);
            for (int i = 0; i < kg; ++i) {
                const double f = ug[i].coef.x();  // the fraction (with its sign)
                addRhs(ug[i], -f * grad);
            }
            const Vec3 along = y > 0.0 ? Vec3(slip / y) : c.normal.unitOrthogonal();
            const Vec3 tangents[2] = {along, c.normal.cross(along)};
            // In an island the majoriser (f1(y) / y along the slip as well): with the exact
            // f1' = 0 of a slide, full steps of a system coupled through movable bodies
            // leave the stick range and cycle, as a rope's friction on a movable body does
            // (rigidFrictionTerm); the majoriser's steps do not overshoot.
            const double along_weight = y > 0.0 && !island_ ? m.df1 : m.f1_over_y;
            const double weights[2] = {bound * along_weight, bound * m.f1_over_y};
            for (int t = 0; t < 2 && fresh; ++t) {
                if (!(weights[t] > 0.0)) continue;  // sliding: no stiffness along the slip
                Direction dt;
                dt.entries = entries(c, tangents[t], dt.u);
                dt.weight = weights[t];
                if (dt.entries > 0) dirs.push_back(dt);
            }
        }
    }

    /// Factorises every string and solves y = A^-1 r; the right-hand sides kept in sc.r.
    void factor() {
        if (sc_.r.size() < count_) sc_.r.resize(count_);
        for (std::size_t i = 0; i < count_; ++i) {
            StringState& s = *strings_[i];
            std::vector<Vec3>& y = sc_.y[i];
            sc_.solvers[i].factor(s);
            sc_.r[i] = s.scratch.blk_rhs;
            y = s.scratch.blk_rhs;
            sc_.solvers[i].solve(s, y);
            for (std::size_t p = 0; p < s.particles(); ++p)
                if (!freeParticle(s, p) || !y[p].allFinite()) y[p].setZero();
        }
        sc_.pool.clear();
        solved_ = 0;
    }

    /// Z = A^-1 U, one solve per direction and string it touches, for the directions added
    /// since the last call (into `pool`).
    void columns() {
        std::vector<Vec3>& scratch = sc_.column;
        for (; solved_ < sc_.dirs.size(); ++solved_) {
            Direction& d = sc_.dirs[solved_];
            d.strings = 0;
            for (int e = 0; e < d.entries; ++e) {
                if (d.u[e].held) continue;  // a body's unknowns: not in the chain's system
                bool known = false;
                for (int i = 0; i < d.strings; ++i) known = known || d.string[i] == d.u[e].string;
                if (!known) d.string[d.strings++] = d.u[e].string;
            }
            for (int i = 0; i < d.strings; ++i) {
                const StringState& s = *strings_[d.string[i]];
                scratch.assign(s.particles(), Vec3::Zero());
                std::size_t first = s.particles();
                for (int e = 0; e < d.entries; ++e)
                    if (d.u[e].string == d.string[i] && !d.u[e].held) {
                        scratch[d.u[e].particle] += d.u[e].coef;
                        first = std::min(first, d.u[e].particle);
                    }
                if (island_) {
                    solveFactored(s.particles(), s.scratch.blk_off.data(), s.scratch.blk_factor.data(),
                                  s.scratch.blk_factor_gain.data(), s.scratch.blk_coupled.data(), scratch.data(), first);
                } else {
                    sc_.solvers[d.string[i]].solve(s, scratch, first);
                }
                for (std::size_t p = 0; p < s.particles(); ++p)
                    if (!freeParticle(s, p) || !scratch[p].allFinite()) scratch[p].setZero();
                d.column[i] = sc_.pool.size();
                sc_.pool.insert(sc_.pool.end(), scratch.begin(), scratch.end());
            }
        }
    }
    /// Direction d's column of Z at particle p of `string` (zero where d does not touch it).
    Vec3 zAt(const Direction& d, std::uint32_t string, std::size_t p) const {
        for (int i = 0; i < d.strings; ++i)
            if (d.string[i] == string) return sc_.pool[d.column[i] + p];
        return Vec3::Zero();
    }

    /// The joint Newton step into the strings' blk_rhs: by one sparse factorisation of the
    /// whole cluster where that pays (sparseStepPays), else by the Woodbury identity,
    /// (K^-1 + U^T Z) z = U^T y, dx = y - Z z.
    void jointStep() {
        const std::vector<Direction>& dirs = sc_.dirs;
        if ((work_.always_sparse || sparseStepPays(dirs.size(), cluster_particles_)) && sparseClusterStep(strings_, dirs, sc_))
            return;
        columns();
        for (std::size_t i = 0; i < count_; ++i) strings_[i]->scratch.blk_rhs = sc_.y[i];
        // The held contacts' gaps in the right-hand side: y = A^-1 (r - U K g) = y - Z K g.
        std::vector<std::size_t>& on = sc_.on;
        on.clear();
        for (std::size_t d = 0; d < dirs.size(); ++d) {
            if (dirs[d].off) continue;
            on.push_back(d);
            if (dirs[d].gap != 0.0) subtractColumn(dirs[d], dirs[d].weight * dirs[d].gap);
        }
        const auto dim = static_cast<Eigen::Index>(on.size());
        if (dim == 0) return;
        ClusterScratch::Impl::Woodbury& wb = sc_.woodbury(dim);
        Eigen::MatrixXd& sys = wb.sys;
        Eigen::VectorXd& rhs = wb.rhs;
        sys.resize(dim, dim);
        rhs.resize(dim);
        for (Eigen::Index r = 0; r < dim; ++r) {
            const Direction& dr = dirs[on[static_cast<std::size_t>(r)]];
            double uy = 0.0;
            for (int e = 0; e < dr.entries; ++e) uy += dr.u[e].coef.dot(strings_[dr.u[e].string]->scratch.blk_rhs[dr.u[e].particle]);
            rhs[r] = uy;
            for (Eigen::Index col = 0; col < dim; ++col) {
                const Direction& dc = dirs[on[static_cast<std::size_t>(col)]];
                double v = 0.0;
                for (int e = 0; e < dr.entries; ++e) v += dr.u[e].coef.dot(zAt(dc, dr.u[e].string, dr.u[e].particle));
                sys(r, col) = v;
            }
            sys(r, r) += 1.0 / dr.weight;
        }
        // Symmetric to rounding; LDLT reads the lower triangle only.
        wb.ldlt.compute(sys);
        Eigen::VectorXd& z = wb.z;
        z = wb.ldlt.solve(rhs);
        if (!z.allFinite()) return;
        for (Eigen::Index r = 0; r < dim; ++r) subtractColumn(dirs[on[static_cast<std::size_t>(r)]], z[r]);
    }
    /// blk_rhs -= f Z_d (direction d's column of Z on each of its strings).
    void subtractColumn(const Direction& d, double f) {
        for (int i = 0; i < d.strings; ++i) {
            std::vector<Vec3>& dx = strings_[d.string[i]]->scratch.blk_rhs;
            const Vec3* zc = &sc_.pool[d.column[i]];
            for (std::size_t p = 0; p < dx.size(); ++p) dx[p] -= f * zc[p];
        }
    }

    /// One Newton step into the strings' blk_rhs: the strings' systems and the contacts that
    /// penetrate now, then the clear contacts that the full step runs into, added (and let
    /// go) in up to kStringPredictRounds rounds, the step solved again after each.
    void newtonStep() {
        assemble();
        factor();
        jointStep();
        findCandidates(stepReach());
        if (plain_next_) return;
        for (int round = 0; round < kStringPredictRounds && predictContacts(); ++round) {
            jointStep();
            findCandidates(stepReach());
        }
    }
    /// Whether the step's model holds a contact with its gap (predictContacts).
    bool heldGaps() const {
        return std::any_of(sc_.dirs.begin(), sc_.dirs.end(), [](const Direction& d) { return !d.off && d.gap != 0.0; });
    }
    /// Holds the clear candidates that the step runs into; true where the set changed, so
    /// that the step stops at a contact instead of the line search shrinking to nothing
    /// against a penalty that switches on. How a contact is held depends on where it was:
    /// - Resting (two strings touching where the step starts, a rope lying on or wrapped
    ///   round another): with its gap in the model, k_c (g + u^T dx)^2 / 2, and let go
    ///   where, held, the step no longer runs into it (the held term would pull the strings
    ///   together): the active set of a semismooth Newton step on the one-sided penalties,
    ///   as a string's own solve holds its rigid contacts. Held with its gap taken as 0
    ///   instead, the contact is a stiff spring where the string is: a rope pulled onto
    ///   another one hovers off it, pressing nothing, and a rope wrapped round a pinned one
    ///   slid at 0.95 of e^(mu theta) by 0.16 m (a quarter turn) to 1 m (a full turn) in a
    ///   second.
    /// - Coming into reach during the step, or a string against itself: a stiff spring
    ///   where it is, never let go. Whipping ropes that meet at speed change their contact
    ///   sets every round with the semismooth set (a 300-segment rope swinging through a
    ///   100-segment one took 47 s for 150 steps instead of 2), and a coiling rod's hairpin
    ///   let go folded through itself (Twist.ClampedRodThatCoilsKeepsItsLink lost a turn
    ///   of its link).
    bool predictContacts() {
        bool changed = false;
        for (std::size_t ci : sc_.candidates) {
            StringPairContact& c = contacts_[ci];
            if (c.active && !sc_.predicted[ci]) continue;
            const bool runs_into = gapAt(c, 1.0) < 0.0;
            if (runs_into == c.active) continue;
            const bool resting = c.start_distance < c.gap * (1.0 + kContactSlop) && c.string != c.partner;
            if (!runs_into && !resting) continue;  // held where it is: it does not pull
            if (!runs_into) {
                c.active = false;
                sc_.predicted[ci] = 0;
                sc_.dirs[sc_.predicted_dir[ci]].off = true;
                changed = true;
                continue;
            }
            Direction dn;
            dn.entries = entries(c, c.normal, dn.u);
            if (dn.entries == 0) continue;  // nothing of it moves
            dn.weight = c.stiffness;
            dn.gap = resting ? gapAt(c, 0.0) : 0.0;
            c.active = true;
            sc_.predicted[ci] = 1;
            sc_.predicted_dir[ci] = sc_.dirs.size();
            sc_.dirs.push_back(dn);
            changed = true;
        }
        return changed;
    }

    /// The cluster's energy alpha of the way along the step (the contacts left out of
    /// `candidates` stay apart along the whole step: no penalty, no friction).
    double energy(double alpha) const {
        double e = 0.0;
        for (const StringState* s : strings_) e += stepEnergy(*s, rigids_, ctx_, alpha);
        for (std::size_t ci : sc_.candidates) addContactEnergy(ci, alpha, e);
        return e;
    }
    /// Adds contact ci's penalty and friction alpha of the way along the step to `e`.
    void addContactEnergy(std::size_t ci, double alpha, double& e) const {
        const StringPairContact& c = contacts_[ci];
        const double g = std::min(0.0, gapAt(c, alpha));
        e += 0.5 * c.stiffness * g * g;
        if (sc_.friction_bound[ci] > 0.0) e += frictionEnergy(ci, alpha);
    }

    /// Backtracking line search on the cluster's energy, then the move; true where no
    /// particle moved by more than the tolerance (converged).
    bool lineSearch() {
        double alpha = 1.0;
        const double e0 = energy(0.0);
        int halving = 0;
        for (; halving < kStringLineSearchHalvings && energy(alpha) > e0; ++halving) alpha *= 0.5;
        // A step that no fraction of lowers the energy, from a model that held contacts with
        // their gaps (which change its gradient, so the step need not descend), is not
        // taken, and the next iteration's step is Newton's on the energy alone (its exact
        // gradient, a positive definite Hessian: a descent direction). Taken instead, a
        // rope wrapped round another one whose joint lay under the wrap gained energy
        // every iteration of a pass and slid off (0.15-3.8 m where it should have held or
        // slid 0.13 m). Otherwise, and where that step too fails, the last fraction is
        // taken, as before (stopping there instead left strings half-solved).
        if (halving == kStringLineSearchHalvings && !plain_next_ && heldGaps() && energy(alpha) > e0) {
            alpha = 0.0;
            plain_next_ = true;
        } else {
            plain_next_ = false;
        }
        double worst = 0.0;
        for (StringState* sp : strings_)
            for (std::size_t p = 0; p < sp->particles(); ++p) {
                if (!freeParticle(*sp, p)) continue;
                const Vec3 dx = alpha * sp->scratch.blk_rhs[p];
                if (!dx.allFinite()) continue;
                sp->x[p] += dx;
                worst = std::max(worst, dx.norm());
            }
        travel_ += 2.0 * worst;
        // A step the line search cut short is no sign of convergence: its move is small
        // because the step was cut (a rope wrapped round another one ended a pass after one
        // step cut to 2^-16, its friction then missing Coulomb's law by 20 times).
        return alpha == 1.0 && worst < tol_;
    }

    /// The pressing forces (the friction bound of the next pass), then the closest points,
    /// shadows and friction weights again. Returns whether they changed: then another pass.
    bool endPass() {
        bool changed = false;
        double moved = 0.0;
        for (StringPairContact& c : contacts_) c.force = skipped(c) ? 0.0 : c.stiffness * std::max(0.0, -gapAt(c, 0.0));
        for (StringPairContact& c : contacts_) {
            const std::size_t i = static_cast<std::size_t>(&c - contacts_.data());
            if (strings_[c.string]->broken[c.segment] || strings_[c.partner]->broken[c.partner_segment]) continue;
            const double s0 = c.s, t0 = c.partner_s;
            const Vec3 n0 = c.normal;
            linearise(c, false);
            if (!sc_.shadowed[i])
                moved = std::max({moved, std::abs(c.s - s0), std::abs(c.partner_s - t0), (c.normal - n0).norm()});
        }
        sc_.was_shadowed = sc_.shadowed;
        shadow();
        changed = sc_.was_shadowed != sc_.shadowed;
        for (StringPairContact& c : contacts_) c.active = !skipped(c) && gapAt(c, 0.0) < 0.0;
        // Friction's bounds follow the new forces: the passes end at a Coulomb solution.
        if (weighFriction() > kFrictionSettled) changed = true;
        return changed || moved > kStringRelinearise;
    }

    /// Springs' forces and rigid row projectors of the final state; the particles a string
    /// contact presses lose the contact force's direction from their tension equations.
    void finish() {
        for (StringState* sp : strings_) {
            sp->scratch.predicted_taut.clear();
            finishChain(*sp, rigids_, ctx_);
        }
        pressRows();
    }
    void pressRows() {
        for (const StringPairContact& c : contacts_) {
            if (skipped(c) || gapAt(c, 0.0) > kContactSlop * c.gap) continue;
            Vec3 dirs_c[2] = {c.normal, Vec3::Zero()};
            if (frictional(c)) {
                const Vec3 slip = slipAt(c, 0.0);
                if (slip.norm() > 0.0) dirs_c[1] = slip / slip.norm();
            }
            UEntry u[4];
            const int k = entries(c, Vec3::Ones(), u);
            for (int i = 0; i < k; ++i) {
                if (u[i].held) continue;
                StringState& s = *strings_[u[i].string];
                for (const Vec3& dir : dirs_c) {
                    const Vec3 left = s.scratch.row_projector[u[i].particle] * dir;  // what is left of it
                    const double len = left.norm();
                    if (len > 1e-6) s.scratch.row_projector[u[i].particle] -= (left / len) * (left / len).transpose();
                    s.scratch.rows_pressed = true;
                }
            }
        }
    }

    const std::vector<StringState*>& strings_;
    std::vector<StringPairContact>& contacts_;
    RigidTable& rigids_;
    const StepContext& ctx_;
    ClusterScratch& work_;
    ClusterScratch::Impl& sc_;
    const std::size_t count_;
    const double inv_h2_;
    double tol_ = 0.0;                    ///< convergence: the largest move, m
    double travel_ = 0.0;                 ///< twice the largest moves summed over this pass, m
    std::size_t solved_ = 0;              ///< directions whose columns of Z are in `pool`
    std::size_t cluster_particles_ = 0;
    bool plain_next_ = false;             ///< the next Newton step holds no contact it runs into
    bool island_ = false;                 ///< a member of an island (the chains are the members')
    std::vector<std::vector<Vec3>> held_rhs_;  ///< per string and particle: the contacts' gradient at glued particles
};

}  // namespace

void solveStringCluster(const std::vector<StringState*>& strings, std::vector<StringPairContact>& contacts,
                        RigidTable& rigids, const StepContext& ctx, ClusterScratch& work) {
    ClusterSolver(strings, contacts, rigids, ctx, work).solve();
}

// --- ClusterIslandMember (cluster_member.hpp) ------------------------------------------------

struct ClusterIslandMember::Impl {
    /// Member k's body slots in the island, from the island's slots of this member's bodies.
    const std::vector<int>& slotsOf(std::size_t k, const std::vector<int>& slot) const {
        std::vector<int>& out = member_slot[k];
        out.resize(node_of[k].size());
        for (std::size_t j = 0; j < out.size(); ++j) out[j] = slot[static_cast<std::size_t>(node_of[k][j])];
        return out;
    }
    /// U_x^T y for a direction: its particles' entries against the strings' blk_rhs.
    double alongBlkRhs(const Direction& d) const {
        double v = 0.0;
        for (int e = 0; e < d.entries; ++e)
            if (!d.u[e].held) v += d.u[e].coef.dot(solver->string(d.u[e].string).scratch.blk_rhs[d.u[e].particle]);
        return v;
    }
    /// U_x^T dx + U_b^T du for a direction: every entry against its particle's move, a
    /// glued one's in its body's step (held_step).
    double alongStep(const Direction& d) const {
        double v = 0.0;
        for (int e = 0; e < d.entries; ++e) {
            const StringState& s = solver->string(d.u[e].string);
            v += d.u[e].coef.dot(d.u[e].held ? s.scratch.held_step[d.u[e].particle] : s.scratch.blk_rhs[d.u[e].particle]);
        }
        return v;
    }
    /// Adds J^T v at glued particle p of member k to the 6-vector of its body in `out`
    /// (rows from `row`), J its motion in its body's unknowns.
    template <class Out>
    void addToBody(std::size_t k, std::size_t p, const Vec3& v, Out&& out) const {
        const int node = members[k].gluedNode(p);
        if (node < 0) return;
        out.template segment<6>(6 * node_of[k][static_cast<std::size_t>(node)]) += members[k].glueJacobianAt(p).transpose() * v;
    }

    std::optional<ClusterSolver> solver;  ///< this step's (it holds the step's references)
    std::vector<StringIslandMember> members;  ///< one per string, in the cluster's order
    std::vector<RigidId> bodies;              ///< every member's bodies, each once
    std::vector<std::vector<int>> node_of;    ///< per member: the index in `bodies` of each of its bodies
    mutable std::vector<std::vector<int>> member_slot;
    std::vector<std::size_t> on;  ///< the directions in the step (not let go)
    Eigen::MatrixXd w;            ///< W = B^T Z: 6 rows a body, a column a direction of `on`
    Eigen::LDLT<Eigen::MatrixXd> c;
    Eigen::MatrixXd schur;        ///< W C^-1 W^T
    Eigen::VectorXd rs;           ///< W C^-1 U^T y
};

ClusterIslandMember::ClusterIslandMember() = default;
ClusterIslandMember::~ClusterIslandMember() = default;
ClusterIslandMember::ClusterIslandMember(ClusterIslandMember&&) noexcept = default;
ClusterIslandMember& ClusterIslandMember::operator=(ClusterIslandMember&&) noexcept = default;

bool ClusterIslandMember::start(const std::vector<StringState*>& strings, std::vector<StringPairContact>& contacts,
                                RigidTable& rigids, const StepContext& ctx, ClusterScratch& work) {
    if (!impl_) impl_ = std::make_unique<Impl>();
    Impl& m = *impl_;
    m.solver.emplace(strings, contacts, rigids, ctx, work);
    m.bodies.clear();
    if (!m.solver->startInIsland()) return false;
    for (StringState* s : strings) s->scratch.held_step.clear();
    m.members.resize(strings.size());
    m.node_of.assign(strings.size(), {});
    m.member_slot.resize(strings.size());
    for (std::size_t k = 0; k < strings.size(); ++k) {
        m.members[k].start(*strings[k], rigids, ctx);
        // Friction with static bodies as in the strings' own solves (the smoothed
        // potential), not an island string's lagged weights: with those, torn pieces lying
        // on the ground under pieces on the bridge's boards kept the second solves from
        // converging in 173 of 416 steps (the scene 3.3x slower); smoothed, the scene costs
        // 1.1x and its unconverged solves are as without the clusters (docs/island-plan.md).
        for (RigidSegmentContact& c : strings[k]->contacts) c.lagged = false;
        for (RigidId b : m.members[k].bodies()) {
            std::size_t at = 0;
            while (at < m.bodies.size() && !(m.bodies[at] == b)) ++at;
            if (at == m.bodies.size()) m.bodies.push_back(b);
            m.node_of[k].push_back(static_cast<int>(at));
        }
    }
    return true;
}

const std::vector<RigidId>& ClusterIslandMember::bodies() const { return impl_->bodies; }

std::size_t ClusterIslandMember::stringCount() const { return impl_->members.size(); }
void ClusterIslandMember::holdStep(const std::vector<int>& slot, const Eigen::VectorXd& du) {
    Impl& m = *impl_;
    for (std::size_t k = 0; k < m.members.size(); ++k) {
        m.members[k].holdStep(m.slotsOf(k, slot), du);
        m.solver->string(k).scratch.held_step.clear();
    }
}

void ClusterIslandMember::beginPass() {
    for (StringIslandMember& member : impl_->members) member.beginPass();
    impl_->solver->beginIslandPass();
}

void ClusterIslandMember::condense(bool fresh) {
    Impl& m = *impl_;
    for (StringIslandMember& member : m.members) member.assembleSystem(fresh);
    m.solver->addIslandTerms(fresh);
    for (StringIslandMember& member : m.members) member.factorAndCondense();  // y = A^-1 r in blk_rhs
    m.solver->islandColumns();
    const std::vector<Direction>& dirs = m.solver->directions();
    m.on.clear();
    for (std::size_t d = 0; d < dirs.size(); ++d)
        if (!dirs[d].off) m.on.push_back(d);
    const auto dim = static_cast<Eigen::Index>(m.on.size());
    const auto nb = static_cast<Eigen::Index>(6 * m.bodies.size());
    m.schur.setZero(nb, nb);
    m.rs.setZero(nb);
    // The contacts' gradient at glued particles is their bodies'.
    for (std::size_t k = 0; k < m.members.size(); ++k) {
        const std::vector<Vec3>& held = m.solver->heldRhs(k);
        for (std::size_t p = 0; p < held.size(); ++p)
            if (!held[p].isZero(0.0)) m.addToBody(k, p, held[p], m.rs);
    }
    if (dim == 0) return;
    Eigen::MatrixXd sys(dim, dim);
    Eigen::VectorXd uy(dim);
    m.w.setZero(nb, dim);
    for (Eigen::Index r = 0; r < dim; ++r) {
        const Direction& dr = dirs[m.on[static_cast<std::size_t>(r)]];
        uy[r] = m.alongBlkRhs(dr);
        for (Eigen::Index col = 0; col < dim; ++col) {
            const Direction& dc = dirs[m.on[static_cast<std::size_t>(col)]];
            double v = 0.0;
            for (int e = 0; e < dr.entries; ++e) v += dr.u[e].coef.dot(m.solver->column(dc, dr.u[e].string, dr.u[e].particle));
            sys(r, col) = v;
        }
        sys(r, r) += 1.0 / dr.weight;
        // W's column: B^T z - U_b, each string's couplings to its bodies (B's 3 x 6 blocks
        // at the particles the bodies' rows touch) against the direction's column of Z, less
        // the direction's own entries at glued particles, J^T u (header).
        for (int e = 0; e < dr.entries; ++e)
            if (dr.u[e].held) m.addToBody(dr.u[e].string, dr.u[e].particle, -dr.u[e].coef, m.w.col(r));
        for (int i = 0; i < dr.strings; ++i) {
            const std::uint32_t k = dr.string[i];
            const StringState& s = m.solver->string(k);
            const StringScratch::NodeScratch& ns = s.scratch.node_scratch;
            for (std::size_t b = 0; b < s.body_nodes.size(); ++b) {
                Vec6 wb = Vec6::Zero();
                for (const auto& [p, blk] : ns.coupling[b]) wb += blk.transpose() * m.solver->column(dr, k, p);
                m.w.block<6, 1>(6 * m.node_of[k][b], r) += wb;
            }
        }
    }
    m.c.compute(sys);  // symmetric to rounding; the lower triangle is read
    const Eigen::MatrixXd cw = m.c.solve(m.w.transpose());
    m.schur.noalias() = m.w * cw;
    m.rs.noalias() += cw.transpose() * uy;
}

void ClusterIslandMember::addTo(const std::vector<int>& slot, Eigen::MatrixXd& system, Eigen::VectorXd& rhs) const {
    const Impl& m = *impl_;
    for (std::size_t k = 0; k < m.members.size(); ++k) m.members[k].addTo(m.slotsOf(k, slot), system, rhs);
    for (std::size_t a = 0; a < m.bodies.size(); ++a) {
        const Eigen::Index ra = 6 * slot[a], ca = static_cast<Eigen::Index>(6 * a);
        rhs.segment<6>(ra) += m.rs.segment<6>(ca);
        for (std::size_t b = 0; b < m.bodies.size(); ++b)
            system.block<6, 6>(ra, 6 * slot[b]) += m.schur.block<6, 6>(ca, static_cast<Eigen::Index>(6 * b));
    }
}

void ClusterIslandMember::addTurningSoftening(const std::vector<int>& slot, std::vector<Mat3>& softening) const {
    const Impl& m = *impl_;
    for (std::size_t k = 0; k < m.members.size(); ++k) m.members[k].addTurningSoftening(m.slotsOf(k, slot), softening);
}

void ClusterIslandMember::backSubstitute(const std::vector<int>& slot, const Eigen::VectorXd& du) {
    Impl& m = *impl_;
    for (std::size_t k = 0; k < m.members.size(); ++k) {
        m.members[k].backSubstitute(m.slotsOf(k, slot), du);
        // Each glued particle's move in its body's step.
        StringState& s = m.solver->string(k);
        s.scratch.held_step.assign(s.particles(), Vec3::Zero());
        for (std::size_t p = 0; p < s.particles(); ++p) {
            const int node = m.members[k].gluedNode(p);
            if (node >= 0) s.scratch.held_step[p] = m.members[k].glueJacobianAt(p) * s.scratch.node_step[static_cast<std::size_t>(node)];
        }
    }
    const auto dim = static_cast<Eigen::Index>(m.on.size());
    if (dim > 0) {
        const std::vector<Direction>& dirs = m.solver->directions();
        Eigen::VectorXd v(dim);
        for (Eigen::Index r = 0; r < dim; ++r) v[r] = m.alongStep(dirs[m.on[static_cast<std::size_t>(r)]]);
        const Eigen::VectorXd t = m.c.solve(v);
        if (t.allFinite())
            for (Eigen::Index r = 0; r < dim; ++r) m.solver->subtractIslandColumn(dirs[m.on[static_cast<std::size_t>(r)]], t[r]);
    }
    m.solver->islandStepKnown();
}

bool ClusterIslandMember::addPredictedContacts() {
    Impl& m = *impl_;
    bool changed = false;
    for (StringIslandMember& member : m.members) changed = member.addPredictedContacts() || changed;
    return m.solver->predictIslandContacts() || changed;
}

double ClusterIslandMember::energy(double alpha) const {
    const Impl& m = *impl_;
    double e = 0.0;
    for (const StringIslandMember& member : m.members) e += member.energy(alpha);
    return e + m.solver->contactEnergy(alpha);
}

double ClusterIslandMember::apply(double alpha, const std::vector<int>& slot, const Eigen::VectorXd& displacement) {
    Impl& m = *impl_;
    m.solver->islandMoves(alpha);
    double worst = 0.0;
    for (std::size_t k = 0; k < m.members.size(); ++k)
        worst = std::max(worst, m.members[k].apply(alpha, m.slotsOf(k, slot), displacement));
    return worst;
}

double ClusterIslandMember::reweigh() {
    Impl& m = *impl_;
    double change = 0.0;
    for (StringIslandMember& member : m.members) change = std::max(change, member.reweigh());
    // A pass whose contacts moved (closest points, normals, shadows) or whose friction
    // missed Coulomb's law with the new forces asks for another.
    return m.solver->endIslandPass() ? std::max(change, 1.0) : change;
}

void ClusterIslandMember::finish(int iterations) {
    Impl& m = *impl_;
    for (StringIslandMember& member : m.members) member.finish(iterations);
    m.solver->finishInIsland();
    for (std::size_t k = 0; k < m.members.size(); ++k) m.solver->string(k).scratch.held_step.clear();
}

}  // namespace tearables::detail
