// Body-body contacts in an island (body_contacts.hpp).
//
// Each contact adds to the island's energy a stiff one-sided penalty on its gap and lagged
// Coulomb friction on its slip, as a string's contacts with bodies do (string/contact_rows.cpp):
//     k/2 min(0, g(d) + allow)^2  +  w/2 |P s(d)|^2,
// g(d) = g + n . (u_a + theta_a x r_a) - n . (u_b + theta_b x r_b)   (r: arm from the centre)
// s(d) = motion + (u_a + theta_a x r_a) - (u_b + theta_b x r_b),      P = I - n n^T,
// w = mu F / max(|P s|, eps), F the contact's normal force where the pass started. Both
// terms are convex in the bodies' displacements d, so the island's Newton iteration with
// its line search converges from any start (Macklin et al. 2019 and IPC, Li et al. 2020,
// solve contact in the same way; shared/notes/islands.md, section 7). The arms are fixed
// where the solve started: the second-order motion of a turning contact is met by the next
// step's contacts, found at the new poses.
#include "island/body_contacts.hpp"

#include <algorithm>
#include <cmath>

namespace tearables::detail {

namespace {

/// The fraction of an overlap that was there at the start of the step (the host's, or a
/// body dropped into another) that the step pushes out; Bullet's contact ERP is the same
/// 0.2. All at once would throw the bodies apart at depth / h.
constexpr double kOverlapRecovery = 0.2;
/// Slip per step below which friction sticks (m): lagged friction holds a load F_t below
/// mu F with a slip of eps F_t / (mu F), so a load at rest creeps by at most eps a step.
constexpr double kStickSlip = 1e-6;

Vec6 jacobian(const Vec3& n, const Vec3& r) {
    Vec6 j;
    j.head<3>() = n;
    j.tail<3>() = r.cross(n);
    return j;
}

bool finite(const Vec3& v) { return v.allFinite(); }

}  // namespace

void prepareBodyContacts(std::vector<BodyContact>& contacts, const RigidTable& rigids) {
    auto keep = [&](BodyContact& c) {
        const PairOrder order = orderPair(c.a, c.b, rigids);
        if (order == PairOrder::Drop) return false;
        if (order == PairOrder::Swap) {
            std::swap(c.a, c.b);
            std::swap(c.point_a, c.point_b);
            c.normal = -c.normal;
            c.motion = -c.motion;
        }
        if (!finite(c.point_a) || !finite(c.point_b) || !finite(c.normal) || !finite(c.motion)) return false;
        const double n = c.normal.norm();
        if (!(std::abs(n - 1.0) < 1e-3)) return false;
        c.normal /= n;
        if (!(c.depth >= 0.0) || !std::isfinite(c.depth)) c.depth = 0.0;
        if (!(c.friction >= 0.0) || !std::isfinite(c.friction)) c.friction = 0.0;
        if (!(c.force >= 0.0) || !std::isfinite(c.force)) c.force = 0.0;
        return true;
    };
    contacts.erase(std::remove_if(contacts.begin(), contacts.end(), [&](BodyContact& c) { return !keep(c); }),
                   contacts.end());
    // One member per pair: the contacts of a pair together, in the order of the pair's first.
    std::stable_sort(contacts.begin(), contacts.end(), [](const BodyContact& x, const BodyContact& y) {
        const auto key = [](const BodyContact& c) { return std::make_pair(c.a.index, c.b.valid() ? c.b.index : ~0u); };
        return key(x) < key(y);
    });
}

void BodyContactMember::start(std::vector<BodyContact>& contacts, std::size_t first, std::size_t count,
                              const RigidTable& rigids, const StepContext& ctx) {
    contacts_ = &contacts;
    first_ = first;
    const BodyContact& c0 = contacts[first];
    const RigidState& a = rigids.bodies[c0.a.index];
    startPair(c0.a, c0.b, rigids);
    double mass = 1.0 / a.inverse_mass;
    if (b_moves_) {
        mass = std::max(mass, 1.0 / rigids.bodies[c0.b.index].inverse_mass);
    }
    stiffness_ = kPairStiffnessFactor * mass * ctx.inv_h * ctx.inv_h;
    rows_.resize(count);
    frictional_ = false;
    for (std::size_t k = 0; k < count; ++k) {
        const BodyContact& c = contacts[first + k];
        Row& r = rows_[k];
        const Vec3& n = c.normal;
        const Vec3 ra = c.point_a - a.position;
        r.ja = jacobian(n, ra);
        r.sa = pointJacobian(ra);
        if (b_moves_) {
            const Vec3 rb = c.point_b - rigids.bodies[c0.b.index].position;
            r.jb = -jacobian(n, rb);
            r.sb = -pointJacobian(rb);
        } else {
            r.jb.setZero();
            r.sb.setZero();
        }
        r.tangent = Mat3::Identity() - n * n.transpose();
        r.motion = c.motion;
        r.gap = n.dot(c.point_a - c.point_b);
        r.allow = (1.0 - kOverlapRecovery) * c.depth;
        r.mu = c.friction;
        r.force = c.force;
        // The last step's normal force with this step's free slip: friction acts from the
        // first pass (a load at rest sticks, a body sliding at v slides at about v h).
        r.weight = r.mu * r.force / std::max((r.tangent * r.motion).norm(), kStickSlip);
        r.held = false;
        frictional_ = frictional_ || r.mu > 0.0;
    }
}

void BodyContactMember::condense(bool fresh) {
    hessian_.setZero();
    gradient_.setZero();
    for (Row& r : rows_) {
        const double g = gapAt(r, disp_a_, disp_b_) + r.allow;
        if (fresh) r.held = g < 0.0;
        // Held with a positive gap (the step runs into it), the model carries the gap:
        // k (g + j . dd)^2 / 2, whose minimum is the overlap the load needs.
        if (r.held) {
            Eigen::Matrix<double, 12, 1> j;
            j << r.ja, r.jb;
            hessian_ += stiffness_ * j * j.transpose();
            gradient_ += stiffness_ * g * j;
        }
        if (r.weight > 0.0) {
            Eigen::Matrix<double, 3, 12> s;
            s << r.tangent * r.sa, r.tangent * r.sb;
            hessian_ += r.weight * s.transpose() * s;
            gradient_ += r.weight * s.transpose() * slipAt(r, disp_a_, disp_b_);
        }
    }
}

// The active set of a semismooth Newton step, as a string's contacts (StringIslandMember):
// a clear contact the full step would run into is held; a held one that is clear now and
// that the step no longer runs into is let go.
bool BodyContactMember::addPredictedContacts() {
    bool changed = false;
    const Vec6 full_a = disp_a_ + du_a_, full_b = disp_b_ + du_b_;
    for (Row& r : rows_) {
        const double after = gapAt(r, full_a, full_b) + r.allow;
        if (!r.held && after < 0.0) {
            r.held = true;
            changed = true;
        } else if (r.held && after > 0.0 && gapAt(r, disp_a_, disp_b_) + r.allow >= 0.0) {
            r.held = false;
            changed = true;
        }
    }
    return changed;
}

double BodyContactMember::energy(double alpha) const {
    const Vec6 da = disp_a_ + alpha * du_a_, db = disp_b_ + alpha * du_b_;
    double e = 0.0;
    for (const Row& r : rows_) {
        const double g = std::min(0.0, gapAt(r, da, db) + r.allow);
        e += 0.5 * stiffness_ * g * g;
        if (r.weight > 0.0) e += 0.5 * r.weight * slipAt(r, da, db).squaredNorm();
    }
    return e;
}

double BodyContactMember::apply(double alpha, const std::vector<int>& slot, const Eigen::VectorXd& displacement) {
    double move = 0.0;
    for (const Row& r : rows_) move = std::max(move, alpha * (r.sa * du_a_ + r.sb * du_b_).norm());
    takeDisplacements(slot, displacement);
    return move / kPairMoveTolerance;
}

double BodyContactMember::reweigh() {
    double change = 0.0;
    for (Row& r : rows_) {
        r.force = stiffness_ * std::max(0.0, -(gapAt(r, disp_a_, disp_b_) + r.allow));
        const double w = r.mu * r.force / std::max(slipAt(r, disp_a_, disp_b_).norm(), kStickSlip);
        const double scale = std::max(w, r.weight);
        if (scale > 0.0) change = std::max(change, std::abs(w - r.weight) / scale);
        r.weight = w;
    }
    return change;
}

void BodyContactMember::finish(int) {
    for (std::size_t k = 0; k < rows_.size(); ++k)
        (*contacts_)[first_ + k].force = stiffness_ * std::max(0.0, -(gapAt(rows_[k], disp_a_, disp_b_) + rows_[k].allow));
}

}  // namespace tearables::detail
