// A string in an island (sim/island.hpp). Its unknowns are its free particles; a particle
// glued to a movable body is a row fixed in the chain that moves with the body's six
// unknowns, x_p = c + R r, linearised dx_p = J du with J = [I, -[r]x]. Each spring of such
// a particle couples its other end to the body (cross block -H J, body block J^T H J,
// gradient J^T f), and the particle's own mass joins its body (m J^T J / h^2). With the
// contacts' rows (contact_rows.cpp), the chain's block tridiagonal A is factorised and
// the string condenses onto its bodies: D - C^T A^-1 C (condenseRows, or condenseNodes in
// strain_limit.cpp). The rotation's second-order term in x_p enters the Hessian by its
// positive part (addTurningStiffness); the island's line search takes the exact energy,
// with glued particles at their bodies' rotated poses.
#include "string/string_island.hpp"

#include "string/strain_limit_internal.hpp"

#include <algorithm>
#include <cmath>

namespace tearables::detail {

namespace {

/// Newton iterations of a pass that count a segment within kTautSlack of its rest length
/// as taut (its stiffness in the Hessian, no force), after which a segment is slack below
/// its rest length exactly. The band lets the first steps see the whole chain a correction
/// would stretch (a chain at its rest length otherwise takes up its load one segment an
/// iteration); kept for the whole solve, it puts a stiffness in the model that the energy
/// lacks, and a piece lying at zero stretch cycles at flat energy instead of converging.
constexpr int kTautBandIterations = 2;
/// addTurningStiffness takes a pull and an arm as parallel below this sin^2 of their angle.
constexpr double kParallelSin2 = 1e-16;

}  // namespace

void StringIslandMember::start(StringState& s, RigidTable& rigids, const StepContext& ctx) {
    string_ = &s;
    rigids_ = &rigids;
    ctx_ = &ctx;
    glued_.clear();
    bodies_.clear();
    const std::size_t n = s.particles();
    s.island_glue = true;
    contact_nodes_ = s.body_nodes.size();
    // The solve's displacements start at zero (an island solved again starts afresh).
    for (BodyNode& node : s.body_nodes) {
        node.impulse.setZero();
        node.displacement.setZero();
        node.linearised_at.setZero();
    }
    glued_index_.assign(n, -1);
    for (std::size_t p = 0; p < n; ++p) {
        if (!s.glue_movable[p]) continue;
        const RigidId body = s.hold[p].body;
        std::size_t node = 0;
        while (node < s.body_nodes.size() && !(s.body_nodes[node].body == body)) ++node;
        if (node == s.body_nodes.size()) {
            s.body_nodes.emplace_back(body);
            s.body_nodes.back().mass = bodyMass(rigids.bodies[body.index]);
        }
        glued_index_[p] = static_cast<int>(glued_.size());
        // Its inertia pulls toward where its own motion and the twist force take it, as a
        // free particle's prediction does: the joints' twist forces sum to zero over each
        // joint's three particles, so the glued end's share moves its body (else the body
        // never feels it and the string's momentum leaks through its ends).
        const Vec3 target = s.x_prev[p] + ctx.h * s.v[p] + ctx.h * ctx.h * cappedTwistForce(s, p) / s.mass[p];
        glued_.push_back({p, node, s.hold[p].point, target});
    }
    // The segments of glued particles, in order, each once.
    glue_segments_.clear();
    for (const Glued& g : glued_)
        for (std::size_t seg : {g.particle - 1, g.particle})
            if (seg < s.segments() && (glue_segments_.empty() || glue_segments_.back() < seg)) glue_segments_.push_back(seg);
    const std::size_t nodes = s.body_nodes.size();
    for (const BodyNode& node : s.body_nodes) bodies_.push_back(node.body);
    s.scratch.node_step.assign(nodes, Vec6::Zero());
    StringScratch::NodeScratch& scratch = s.scratch.node_scratch;
    if (scratch.diag.size() < nodes) {
        scratch.diag.resize(nodes);
        scratch.rhs.resize(nodes);
        scratch.coupling.resize(nodes);
    }
    setContactStiffness(s, rigids, ctx.inv_h * ctx.inv_h);
    // Friction with a movable body is the smoothed Coulomb potential, as in a string's own
    // solve, with the majorising Hessian (rigidFrictionTerm): the lagged weights do not
    // reach Coulomb's law in an island's passes (a rope over a movable drum slides at 0.95
    // of the capstan ratio). Friction with a static body (the ground) keeps the lagged
    // weights: with the smoothed potential there, islands whose torn ropes slide on the
    // ground stall at their iteration cap (docs/island-baseline.md).
    for (RigidSegmentContact& c : s.contacts) c.lagged = c.node < 0;
    seed_friction_ = true;
}

/// Remembered contacts (ContactMemory) that stick where the solve starts (slip below eps)
/// start with friction: the lagged weight mu N / eps, the last step's N. A sliding
/// one starts without, as a new contact does, and takes its weight after the first pass:
/// seeded with mu N / |u_t| from the start's slip, a box resting on two ropes slid off them
/// at 2 cm/s (a sliding fixed point of the lagged weights), and seeded with the last step's
/// weight, an accelerating slide was dragged by more than mu N (the bridge benchmark's
/// solves took 41 Newton iterations and 21% ended at their cap). Needs the planes
/// linearised where the solve starts (the step's first beginPass).
void StringIslandMember::seedFriction() {
    StringState& s = *string_;
    for (RigidSegmentContact& c : s.contacts) {
        if (!c.lagged || !c.remembered || !(c.friction_normal > 0.0)) continue;
        const std::size_t j = c.segment;
        const Vec3 slip = rigidSlip(s, c, (1.0 - c.s) * s.x[j] + c.s * s.x[j + 1]);
        if (slip.norm() >= slipSmoothing(c)) continue;
        c.friction_weight = c.friction * c.friction_normal / slipSmoothing(c);
    }
}

/// A glued particle's correction (prepareStrainLimit left it in blk_rhs) is its body's at
/// that point.
void StringIslandMember::addWarmHints(const std::vector<int>& slot, std::vector<Mat6>& normal, Eigen::VectorXd& rhs) const {
    for (const Glued& g : glued_) {
        const Mat36 j = glueJacobian(g);
        const std::size_t b = static_cast<std::size_t>(slot[g.node]);
        normal[b] += j.transpose() * j;
        rhs.segment<6>(static_cast<Eigen::Index>(6 * b)) += j.transpose() * string_->scratch.blk_rhs[g.particle];
    }
}

/// The particles' step is the last step's correction, which prepareStrainLimit left in
/// blk_rhs for this (zero where it has none, and for pinned particles).
void StringIslandMember::warmStep(const std::vector<int>& slot, const Eigen::VectorXd& du) {
    StringState& s = *string_;
    for (std::size_t b = 0; b < s.body_nodes.size(); ++b) s.scratch.node_step[b] = du.segment<6>(6 * slot[b]);
}

void StringIslandMember::holdStep(const std::vector<int>& slot, const Eigen::VectorXd& du) {
    warmStep(slot, du);
    std::fill(string_->scratch.blk_rhs.begin(), string_->scratch.blk_rhs.end(), Vec3::Zero());
}

void StringIslandMember::beginPass() {
    linearisePlanes(*string_, *rigids_);
    if (seed_friction_) seedFriction();
    seed_friction_ = false;
    iteration_ = 0;
}

void StringIslandMember::assembleGlue(bool hessian) {
    StringScratch::NodeScratch& ns = string_->scratch.node_scratch;
    const double inv_h2 = ctx_->inv_h * ctx_->inv_h;
    if (hessian) cross_.clear();
    // The glued particle's own inertia, about where its own velocity takes it.
    for (const Glued& g : glued_) {
        const Mat36 j = glueJacobian(g);
        const double w = string_->mass[g.particle] * inv_h2;
        if (hessian) ns.diag[g.node] += w * j.transpose() * j;
        ns.rhs[g.node] -= w * j.transpose() * (string_->x[g.particle] - g.inertial);
    }
    // The springs of glued particles: energy of x_{j+1} - x_j, force f on j toward j + 1.
    pull_.assign(glued_.size(), Vec3::Zero());
    for (std::size_t seg : glue_segments_) {
        const int ga = glued_index_[seg], gb = glued_index_[seg + 1];
        Mat3 hess;
        Vec3 force;
        if (!springRow(*string_, *ctx_, seg, hess, force)) continue;
        Mat36 ja, jb;
        if (ga >= 0) {
            const Glued& g = glued_[static_cast<std::size_t>(ga)];
            ja = glueJacobian(g);
            ns.rhs[g.node] += ja.transpose() * force;
            pull_[static_cast<std::size_t>(ga)] += force;
            if (hessian) {
                ns.diag[g.node] += ja.transpose() * hess * ja;
                if (gb < 0 && !fixedRow(*string_, seg + 1)) ns.coupling[g.node].emplace_back(seg + 1, -hess * ja);
            }
        }
        if (gb >= 0) {
            const Glued& g = glued_[static_cast<std::size_t>(gb)];
            jb = glueJacobian(g);
            ns.rhs[g.node] -= jb.transpose() * force;
            pull_[static_cast<std::size_t>(gb)] -= force;
            if (hessian) {
                ns.diag[g.node] += jb.transpose() * hess * jb;
                if (ga < 0 && !fixedRow(*string_, seg)) ns.coupling[g.node].emplace_back(seg, -hess * jb);
            }
        }
        if (hessian && ga >= 0 && gb >= 0) {
            addCross(glued_[static_cast<std::size_t>(ga)].node, glued_[static_cast<std::size_t>(gb)].node, -ja.transpose() * hess * jb);
        }
    }
}

Mat36 StringIslandMember::glueJacobian(const Glued& g) const {
    return pointJacobian(string_->x[g.particle] - rigids_->bodies[string_->body_nodes[g.node].body.index].position);
}

void StringIslandMember::addCross(std::size_t a, std::size_t b, const Mat6& block) {
    if (a == b) {
        string_->scratch.node_scratch.diag[a] += block + block.transpose();
    } else {
        cross_.push_back({a, b, block});
    }
}

/// A contact on a segment whose end is glued: the contact point x(s) = (1 - s) x_j +
/// s x_{j+1} moves with the glued end's body by its share w = 1 - s or s, dx(s) = w J du
/// (J = [I, -[r]x], as for the glue's springs). assembleContactCoupling holds a glued end
/// as a fixed row, so without this that share of the contact's force acts on no body while
/// the touched body takes the whole reaction: the island's momentum changes by w F h a
/// step. The share joins the glued end's body: its block and gradient, its couplings with
/// the segment's free end, with the touched body and with the other end's body where that
/// end is glued too (the energy, and the line search, have the glued ends on their bodies).
void StringIslandMember::assembleGlueContacts() {
    StringState& s = *string_;
    for (const RigidSegmentContact& c : s.contacts) {
        const std::size_t j = c.segment;
        if (s.broken[j] || (glued_index_[j] < 0 && glued_index_[j + 1] < 0)) continue;
        const Vec3 xs = (1.0 - c.s) * s.x[j] + c.s * s.x[j + 1];
        const Vec3& n = c.plane_normal;
        if (c.active) {
            // k_c g^2 / 2 (assembleContactCoupling's model): residual g n, Jacobian n n^T in
            // x(s) and n a^T in the touched body's motion (a = rigidGapBodyGradient).
            const double gap = rigidGap(s, c, xs);
            const double g = c.predicted ? gap : std::min(0.0, gap);
            const Mat3 nnt = n * n.transpose();
            const Mat36 body = n * rigidGapBodyGradient(c).transpose();
            addGlueShare(c, c.stiffness * nnt, c.stiffness * g * n, nnt, body);
        }
        if (hasFriction(c)) {
            const FrictionTerm f = rigidFrictionTerm(c, rigidSlip(s, c, xs));
            addGlueShare(c, f.hessian, f.gradient, f.tangent, rigidSlipBodyJacobian(c, f.tangent));
        }
    }
}

void StringIslandMember::addGlueShare(const RigidSegmentContact& c, const Mat3& hess, const Vec3& grad, const Mat3& along,
                                      const Mat36& body) {
    StringState& s = *string_;
    StringScratch::NodeScratch& ns = s.scratch.node_scratch;
    const std::size_t ends[2] = {c.segment, c.segment + 1};
    const double weights[2] = {1.0 - c.s, c.s};
    Mat36 share[2];
    for (int e = 0; e < 2; ++e) {
        const int gi = glued_index_[ends[e]];
        if (gi >= 0) share[e] = weights[e] * along * glueJacobian(glued_[static_cast<std::size_t>(gi)]);
    }
    for (int e = 0; e < 2; ++e) {
        const int gi = glued_index_[ends[e]];
        if (gi < 0) continue;
        const std::size_t node = glued_[static_cast<std::size_t>(gi)].node;
        const Mat36 hs = hess * share[e];
        ns.diag[node] += share[e].transpose() * hs;
        ns.rhs[node] -= share[e].transpose() * grad;
        const int other = 1 - e;
        const std::size_t q = ends[other];
        const int go = glued_index_[q];
        if (go < 0 && !fixedRow(s, q)) ns.coupling[node].emplace_back(q, weights[other] * along * hs);
        if (c.node >= 0) addCross(node, static_cast<std::size_t>(c.node), hs.transpose() * body);
        if (e == 0 && go >= 0) addCross(node, glued_[static_cast<std::size_t>(go)].node, hs.transpose() * share[other]);
    }
}

/// The pull F at arm r turns with the body: x_p = c + r + theta x r + theta x (theta x r) / 2
/// to second order, so the energy's Hessian in theta gains (F . r) I - (F r^T + r F^T) / 2.
/// Its positive part joins the member's system; its negative part (softening_) is left to
/// the island, which adds it where the body's inertia keeps the system positive definite:
/// without it Newton converges only linearly where held points carry load
/// (docs/island-baseline.md, "The turn's whole Hessian").
///
/// The split is closed-form. With a = F / |F|, b = r / |r| and c = a . b, the symmetric part
/// (F r^T + r F^T) / 2 has eigenvalues |F||r| (c + 1) / 2 along a + b, |F||r| (c - 1) / 2
/// along a - b and 0 along a x b, so the Hessian's are |F||r| (c - 1) / 2 <= 0 along a + b,
/// |F||r| (c + 1) / 2 >= 0 along a - b and F . r along a x b. Where F and r are parallel
/// the Hessian is (F . r) (I - b b^T), all of one sign.
void StringIslandMember::addTurningStiffness() {
    StringScratch::NodeScratch& ns = string_->scratch.node_scratch;
    softening_.assign(string_->body_nodes.size(), Mat3::Zero());
    for (std::size_t k = 0; k < glued_.size(); ++k) {
        const Glued& g = glued_[k];
        const Vec3& f = pull_[k];
        const Vec3 r = string_->x[g.particle] - rigids_->bodies[string_->body_nodes[g.node].body.index].position;
        const double fn = f.norm(), rn = r.norm();
        if (!(fn > 0.0) || !(rn > 0.0)) continue;
        const Vec3 a = f / fn, b = r / rn;
        const double fr = f.dot(r);
        const Vec3 axis = a.cross(b);
        const double sin2 = axis.squaredNorm();
        Mat3 kept, left;
        if (sin2 < kParallelSin2) {
            const Mat3 geo = fr * (Mat3::Identity() - b * b.transpose());
            kept = fr > 0.0 ? geo : Mat3::Zero();
            left = fr > 0.0 ? Mat3::Zero() : geo;
        } else {
            const Vec3 plus = (a + b).normalized(), minus = (a - b).normalized(), n = axis / std::sqrt(sin2);
            const double c = a.dot(b);
            const Mat3 across = n * n.transpose();
            kept = (0.5 * fn * rn * (c + 1.0)) * (minus * minus.transpose()) + std::max(fr, 0.0) * across;
            left = (0.5 * fn * rn * (c - 1.0)) * (plus * plus.transpose()) + std::min(fr, 0.0) * across;
        }
        ns.diag[g.node].bottomRightCorner<3, 3>() += kept;
        softening_[g.node] += left;
    }
}

void StringIslandMember::addTurningSoftening(const std::vector<int>& slot, std::vector<Mat3>& softening) const {
    for (std::size_t b = 0; b < softening_.size(); ++b) softening[static_cast<std::size_t>(slot[b])] += softening_[b];
}

void StringIslandMember::condense(bool fresh) {
    assembleSystem(fresh);
    factorAndCondense();
}

void StringIslandMember::assembleSystem(bool fresh) {
    StringState& s = *string_;
    if (fresh) {
        s.scratch.exact_slack = iteration_++ >= kTautBandIterations;
        for (RigidSegmentContact& c : s.contacts) {
            const std::size_t j = c.segment;
            c.active = !s.broken[j] && rigidGap(s, c, (1.0 - c.s) * s.x[j] + c.s * s.x[j + 1]) < 0.0;
            c.predicted = false;
        }
        s.scratch.predicted_taut.clear();
    }
    assembleChain(s, *rigids_, *ctx_, nullptr);
    StringScratch::NodeScratch& ns = s.scratch.node_scratch;
    const std::size_t nodes = s.body_nodes.size();
    for (std::size_t b = 0; b < nodes; ++b) {
        ns.diag[b].setZero();
        ns.rhs[b].setZero();
        ns.coupling[b].clear();
    }
    assembleContactCoupling(s, ns);
    assembleGlue(true);
    assembleGlueContacts();
    addTurningStiffness();
}

void StringIslandMember::factorAndCondense() {
    StringState& s = *string_;
    StringScratch::NodeScratch& ns = s.scratch.node_scratch;
    factorChain(s);
    if (condenseRows()) return;
    solveFactored(s.particles(), s.scratch.blk_off.data(), s.scratch.blk_factor.data(), s.scratch.blk_factor_gain.data(),
                  s.scratch.blk_coupled.data(), s.scratch.blk_rhs.data());  // y = A^-1 r
    condenseNodes(s, ns);
}

/// A chord iteration: the gradient here, against the chain's factorisation and the
/// condensed system of the last condense(). Only for a string that touches no body (its
/// contacts' rows would change with the state, and their active set with the step) and
/// only where no segment changed branch since (assembleChainGradient).
bool StringIslandMember::condenseChord() {
    StringState& s = *string_;
    if (!s.contacts.empty()) return false;
    // The band's end (kTautBandIterations) changes the model only where a segment lies
    // in the band, whose branch then changes.
    const bool exact_slack = s.scratch.exact_slack;
    s.scratch.exact_slack = iteration_ >= kTautBandIterations;
    if (!assembleChainGradient(s, *ctx_)) {
        s.scratch.exact_slack = exact_slack;
        return false;
    }
    ++iteration_;
    StringScratch::NodeScratch& ns = s.scratch.node_scratch;
    for (std::size_t b = 0; b < s.body_nodes.size(); ++b) ns.rhs[b].setZero();
    assembleGlue(false);
    solveFactored(s.particles(), s.scratch.blk_off.data(), s.scratch.blk_factor.data(), s.scratch.blk_factor_gain.data(),
                  s.scratch.blk_coupled.data(), s.scratch.blk_rhs.data());  // y = A^-1 r
    condenseRhs();
    return true;
}

void StringIslandMember::condenseRhs() {
    StringState& s = *string_;
    StringScratch::NodeScratch& ns = s.scratch.node_scratch;
    if (!by_rows_) {
        condenseNodesRhs(s, ns);
        return;
    }
    const std::size_t nodes = s.body_nodes.size();
    ns.rs.resize(static_cast<Eigen::Index>(6 * nodes));
    for (std::size_t b = 0; b < nodes; ++b) ns.rs.segment<6>(static_cast<Eigen::Index>(6 * b)) = ns.rhs[b];
    Eigen::VectorXd y_rows(static_cast<Eigen::Index>(3 * rows_.size()));
    for (std::size_t k = 0; k < rows_.size(); ++k) y_rows.segment<3>(static_cast<Eigen::Index>(3 * k)) = s.scratch.blk_rhs[rows_[k]];
    ns.rs.noalias() -= rows_coupling_.transpose() * y_rows;
}

void StringIslandMember::addRhsTo(const std::vector<int>& slot, Eigen::VectorXd& rhs) const {
    const StringScratch::NodeScratch& ns = string_->scratch.node_scratch;
    for (std::size_t a = 0; a < string_->body_nodes.size(); ++a)
        rhs.segment<6>(6 * slot[a]) += ns.rs.segment<6>(static_cast<Eigen::Index>(6 * a));
}

void StringIslandMember::addTo(const std::vector<int>& slot, Eigen::MatrixXd& system, Eigen::VectorXd& rhs) const {
    const StringScratch::NodeScratch& ns = string_->scratch.node_scratch;
    const std::size_t nodes = string_->body_nodes.size();
    for (std::size_t a = 0; a < nodes; ++a) {
        const Eigen::Index ra = 6 * slot[a];
        rhs.segment<6>(ra) += ns.rs.segment<6>(static_cast<Eigen::Index>(6 * a));
        for (std::size_t b = 0; b < nodes; ++b)
            system.block<6, 6>(ra, 6 * slot[b]) +=
                ns.schur.block<6, 6>(static_cast<Eigen::Index>(6 * a), static_cast<Eigen::Index>(6 * b));
    }
    for (const Cross& c : cross_) {
        system.block<6, 6>(6 * slot[c.a], 6 * slot[c.b]) += c.block;
        system.block<6, 6>(6 * slot[c.b], 6 * slot[c.a]) += c.block.transpose();
    }
}

void StringIslandMember::backSubstitute(const std::vector<int>& slot, const Eigen::VectorXd& du) {
    const std::size_t nodes = string_->body_nodes.size();
    Eigen::VectorXd& local = string_->scratch.node_scratch.du;
    local.resize(static_cast<Eigen::Index>(6 * nodes));
    for (std::size_t b = 0; b < nodes; ++b) local.segment<6>(static_cast<Eigen::Index>(6 * b)) = du.segment<6>(6 * slot[b]);
    if (!by_rows_) {
        backSubstituteNodes(*string_, local);
        return;
    }
    // dx = y - A^-1 C du, C du nonzero at the coupled rows only: their columns of A^-1.
    StringState& s = *string_;
    const Eigen::VectorXd z = rows_coupling_ * local;
    for (std::size_t c = 0; c < 3 * rows_.size(); ++c) {
        const double f = z[static_cast<Eigen::Index>(c)];
        if (f == 0.0) continue;
        const std::vector<Vec3>& column = s.scratch.node_columns[c];
        for (std::size_t p = 0; p < s.particles(); ++p) s.scratch.blk_rhs[p] -= f * column[p];
    }
    for (std::size_t b = 0; b < nodes; ++b) s.scratch.node_step[b] = local.segment<6>(static_cast<Eigen::Index>(6 * b));
}

/// The Schur complement through the coupled rows R (the particles the bodies' rows touch)
/// where they are fewer than half the body unknowns: D - B^T G B, r_b - B^T y_R, with G the
/// 3|R| x 3|R| block of A^-1 at R (3 columns a row) and B the couplings stacked by row.
/// A rope glued to two boards couples two rows: 6 solves instead of 12. Solves y = A^-1 r
/// (blk_rhs) with the columns; returns false, having solved nothing, where R is too large.
bool StringIslandMember::condenseRows() {
    StringState& s = *string_;
    StringScratch::NodeScratch& ns = s.scratch.node_scratch;
    const std::size_t n = s.particles();
    const std::size_t nodes = s.body_nodes.size();
    rows_.clear();
    row_of_.resize(n, -1);
    for (std::size_t b = 0; b < nodes; ++b)
        for (const auto& entry : ns.coupling[b])
            if (row_of_[entry.first] < 0) {
                row_of_[entry.first] = static_cast<int>(rows_.size());
                rows_.push_back(entry.first);
            }
    by_rows_ = 3 * rows_.size() < 6 * nodes;
    if (!by_rows_) {
        for (std::size_t q : rows_) row_of_[q] = -1;
        return false;
    }
    const Eigen::Index dim = static_cast<Eigen::Index>(3 * rows_.size());
    rows_coupling_.setZero(dim, static_cast<Eigen::Index>(6 * nodes));
    for (std::size_t b = 0; b < nodes; ++b)
        for (const auto& [p, blk] : ns.coupling[b])
            rows_coupling_.block<3, 6>(3 * row_of_[p], static_cast<Eigen::Index>(6 * b)) += blk;
    if (s.scratch.node_columns.size() < static_cast<std::size_t>(dim)) s.scratch.node_columns.resize(static_cast<std::size_t>(dim));
    // y = A^-1 r and the columns of A^-1 at the rows, solved together.
    std::vector<Vec3*>& columns = s.scratch.column_pointers;
    std::vector<std::size_t>& firsts = s.scratch.column_firsts;
    columns.assign(1, s.scratch.blk_rhs.data());
    firsts.assign(1, 0);
    for (std::size_t k = 0; k < rows_.size(); ++k) {
        for (int c = 0; c < 3; ++c) {
            std::vector<Vec3>& column = s.scratch.node_columns[3 * k + static_cast<std::size_t>(c)];
            column.assign(n, Vec3::Zero());
            column[rows_[k]][c] = 1.0;
            columns.push_back(column.data());
            firsts.push_back(rows_[k]);
        }
    }
    solveFactoredColumns(n, s.scratch.blk_off.data(), s.scratch.blk_factor.data(), s.scratch.blk_factor_gain.data(),
                         s.scratch.blk_coupled.data(), columns.data(), firsts.data(), columns.size());
    rows_inverse_.resize(dim, dim);
    for (std::size_t k = 0; k < 3 * rows_.size(); ++k)
        for (std::size_t k2 = 0; k2 < rows_.size(); ++k2)
            rows_inverse_.block<3, 1>(static_cast<Eigen::Index>(3 * k2), static_cast<Eigen::Index>(k)) = s.scratch.node_columns[k][rows_[k2]];
    for (std::size_t q : rows_) row_of_[q] = -1;
    const Eigen::Index nd = static_cast<Eigen::Index>(6 * nodes);
    ns.schur.setZero(nd, nd);
    for (std::size_t b = 0; b < nodes; ++b)
        ns.schur.block<6, 6>(static_cast<Eigen::Index>(6 * b), static_cast<Eigen::Index>(6 * b)) = ns.diag[b];
    ns.schur.noalias() -= rows_coupling_.transpose() * rows_inverse_ * rows_coupling_;
    condenseRhs();
    return true;
}

/// The contacts that are clear now are held where the step runs into them and let go
/// where, held, it no longer does (their model, carrying the gap, would pull the string
/// onto the plane): the active set of a semismooth Newton step on the penalties. Those
/// that penetrate now stay: their model is the energy's own.
bool StringIslandMember::addPredictedContacts() {
    StringState& s = *string_;
    held_step_.assign(s.particles(), Vec3::Zero());
    for (const Glued& g : glued_) held_step_[g.particle] = glueJacobian(g) * s.scratch.node_step[g.node];
    const bool contacts = predictContacts(s, &held_step_);
    return predictSprings(s, *ctx_, &held_step_) || contacts;
}

Vec3 StringIslandMember::trialGlue(const Glued& g, double alpha) const {
    const BodyNode& node = string_->body_nodes[g.node];
    const RigidState& body = rigids_->bodies[node.body.index];
    const Vec6 step = alpha * string_->scratch.node_step[g.node];
    const Vec3 turn = (node.displacement - node.linearised_at).tail<3>();
    const Quat q = (rotationBy(turn + step.tail<3>()) * rotationBy(turn).conjugate() * body.orientation).normalized();
    return body.position + step.head<3>() + q * g.local;
}

double StringIslandMember::energy(double alpha) const {
    const StringState& s = *string_;
    const std::size_t n = s.particles();
    const double inv_h2 = ctx_->inv_h * ctx_->inv_h;
    // The trial positions: free particles along their step, glued ones on their bodies.
    std::vector<Vec3>& trial = trial_;
    trial.resize(n);
    for (std::size_t p = 0; p < n; ++p) {
        if (glued_index_[p] >= 0) {
            trial[p] = trialGlue(glued_[static_cast<std::size_t>(glued_index_[p])], alpha);
        } else {
            trial[p] = fixedRow(s, p) ? s.x[p] : Vec3(s.x[p] + alpha * s.scratch.blk_rhs[p]);
        }
    }
    double e = 0.0;
    for (std::size_t p = 0; p < n; ++p)
        if (s.hold[p].kind == ParticleHold::Kind::Free) e += 0.5 * s.mass[p] * inv_h2 * (trial[p] - s.x_pred[p]).squaredNorm();
    for (const Glued& g : glued_)
        e += 0.5 * s.mass[g.particle] * inv_h2 * (trial[g.particle] - g.inertial).squaredNorm();
    return addMaterialEnergy(s, *ctx_, alpha, [&trial](std::size_t p) -> const Vec3& { return trial[p]; }, e);
}

double StringIslandMember::apply(double alpha, const std::vector<int>& slot, const Eigen::VectorXd& displacement) {
    StringState& s = *string_;
    for (std::size_t b = 0; b < s.body_nodes.size(); ++b) s.body_nodes[b].displacement = displacement.segment<6>(6 * slot[b]);
    // The bodies' moves (their translation) count as the particles' do.
    double worst_squared = 0.0;
    for (const Vec6& step : s.scratch.node_step) worst_squared = std::max(worst_squared, (alpha * step.head<3>()).squaredNorm());
    for (std::size_t p = 0; p < s.particles(); ++p) {
        Vec3 move = Vec3::Zero();
        if (glued_index_[p] >= 0) {
            const Vec3 x = gluePoint(rigids_->bodies[s.hold[p].body.index], s.hold[p].point);
            move = x - s.x[p];
            s.x[p] = x;
        } else if (!fixedRow(s, p)) {
            move = alpha * s.scratch.blk_rhs[p];
            if (!move.allFinite()) continue;
            s.x[p] += move;
        }
        worst_squared = std::max(worst_squared, move.squaredNorm());
    }
    return std::sqrt(worst_squared) / (ctx_->settings->strain_tolerance * s.shortest_rest);
}

bool StringIslandMember::frictional() const {
    return std::any_of(string_->contacts.begin(), string_->contacts.end(), [](const RigidSegmentContact& c) { return c.friction > 0.0; });
}

double StringIslandMember::reweigh() { return weighRigidFriction(*string_, true); }

void StringIslandMember::finish(int iterations) {
    StringState& s = *string_;
    for (RigidSegmentContact& c : s.contacts) {
        const std::size_t j = c.segment;
        c.active = !s.broken[j] && rigidGap(s, c, (1.0 - c.s) * s.x[j] + c.s * s.x[j + 1]) < 0.0;
        c.predicted = false;
    }
    s.scratch.predicted_taut.clear();
    finishChain(s, *rigids_, *ctx_);
    // What the segments gave each glued particle (x h^2): their final pull, the impulse the
    // tension solve reads for a glued row.
    const double h2 = ctx_->h * ctx_->h;
    for (const Glued& g : glued_) {
        const std::size_t p = g.particle;
        Vec3 pull = Vec3::Zero();
        if (p > 0 && !s.broken[p - 1]) pull -= s.spring_force[p - 1] * (s.x[p] - s.x[p - 1]).normalized();
        if (p + 1 < s.particles() && !s.broken[p]) pull += s.spring_force[p] * (s.x[p + 1] - s.x[p]).normalized();
        s.glue_impulse[p] = pull * h2;
    }
    s.body_nodes.resize(contact_nodes_);
    s.scratch.node_step.resize(contact_nodes_);
    s.island_glue = false;
    s.scratch.exact_slack = false;
    s.diagnostics.strain_newton_iterations += iterations;
}

}  // namespace tearables::detail
