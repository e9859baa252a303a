// A string's velocities and rest lengths, set from outside (tearables/controls.hpp), and a
// winch that hauls a pinned end's rope in or pays it out by changing rest lengths.
#include "tearables/controls.hpp"

#include "world/world_access.hpp"

#include <algorithm>
#include <cmath>
#include <string>

namespace tearables {

void setVelocities(World& world, StringId id, const std::vector<Vec3>& velocities) {
    (void)world.desc(id);  // InvalidInput("string"), a stale id named as such
    detail::StringState& s = (*detail::WorldAccess::parts(world).strings)[id.index];
    const std::size_t n = s.particles();
    if (velocities.size() != 1 && velocities.size() != n)
        throw InvalidInput("velocities", "needs one velocity or one per particle (" + std::to_string(n) + "), got " +
                                             std::to_string(velocities.size()));
    const double max_speed = world.settings().max_speed;
    for (std::size_t i = 0; i < velocities.size(); ++i) {
        const std::string field = "velocities[" + std::to_string(i) + "]";
        if (!velocities[i].allFinite()) throw InvalidInput(field, "must be finite");
        if (velocities[i].norm() > max_speed)
            throw InvalidInput(field, "faster than WorldSettings::max_speed (" + std::to_string(max_speed) + " m/s)");
    }
    for (std::size_t p = 0; p < n; ++p) {
        if (s.hold[p].kind != detail::ParticleHold::Kind::Free) continue;
        s.v[p] = velocities.size() == 1 ? velocities[0] : velocities[p];
        s.v_prev[p] = s.v[p];  // a uniform history: BDF2 starts from it
    }
}


namespace {

void checkMode(RestMass mode) {
    if (mode != RestMass::Conserve && mode != RestMass::Add) throw InvalidInput("mode", "must be RestMass::Conserve or RestMass::Add");
}

/// Segment j to `length`: compliance L / (E A), the strain limit and the length plasticity
/// starts from scale with it; with RestMass::Add its ends gain (lose) rho A dL / 2 each.
void resize(detail::StringState& s, std::size_t j, double length, RestMass mode) {
    const double ratio = length / s.rest_length[j];
    const double area = 3.14159265358979323846 * s.desc.radius * s.desc.radius;
    if (mode == RestMass::Add) {
        const double half = 0.5 * s.desc.density * area * (length - s.rest_length[j]);
        for (std::size_t p : {j, j + 1}) {
            const double m = std::max(s.mass[p] + half, 1e-15);
            s.csm_mass[p] *= m / s.mass[p];
            s.mass[p] = m;
            s.inv_mass[p] = 1.0 / m;
        }
        s.twist_inertia[j] *= ratio;
    }
    s.rest_length[j] = length;
    s.original_length[j] *= ratio;
    s.max_length[j] *= ratio;
    s.compliance[j] *= ratio;
    s.shortest_rest = *std::min_element(s.rest_length.begin(), s.rest_length.end());
    detail::updateRestShape(s);
    detail::updateTwistStiffness(s);
}

}  // namespace

void setRestLength(World& world, StringId id, int segment, double length, RestMass mode) {
    (void)world.desc(id);
    detail::StringState& s = (*detail::WorldAccess::parts(world).strings)[id.index];
    const int n = static_cast<int>(s.segments());
    if (segment < -n || segment >= n)
        throw InvalidInput("segment", "segment index " + std::to_string(segment) + " out of range (the string has " + std::to_string(n) + " segments)");
    if (!std::isfinite(length) || length < 1e-6 || length > 1e6) throw InvalidInput("length", "must be in [1e-6, 1e6] m");
    checkMode(mode);
    resize(s, static_cast<std::size_t>(segment < 0 ? segment + n : segment), length, mode);
}

void reel(World& world, StringId id, int end, double change, RestMass mode) {
    (void)world.desc(id);
    detail::StringState& s = (*detail::WorldAccess::parts(world).strings)[id.index];
    if (end != 0 && end != -1) throw InvalidInput("end", "must be 0 (first) or -1 (last), got " + std::to_string(end));
    const std::size_t m = s.segments();
    auto particle = [&](std::size_t k) { return end == 0 ? k : m - k; };     // k-th particle from the winch
    auto segmentAt = [&](std::size_t k) { return end == 0 ? k : m - 1 - k; };  // k-th segment from the winch
    const detail::ParticleHold& winch = s.hold[particle(0)];
    if (winch.kind != detail::ParticleHold::Kind::Pin) throw InvalidInput("end", "is not pinned: a winch is a pinned end");
    if (!std::isfinite(change) || std::abs(change) > 1e6) throw InvalidInput("change", "must be finite, at most 1e6 m either way");
    checkMode(mode);
    const Vec3 drum = winch.point;
    // The rope already wound: particles pinned at the drum next to the winch.
    std::size_t k = 0;
    while (k + 1 < m && s.hold[particle(k + 1)].kind == detail::ParticleHold::Kind::Pin && s.hold[particle(k + 1)].point == drum) ++k;
    if (change > 0.0) {
        resize(s, segmentAt(k), s.rest_length[segmentAt(k)] + change, mode);
        return;
    }
    double left = -change;
    while (left > 0.0 && k < m) {
        const std::size_t j = segmentAt(k);
        const double initial = (s.desc.points[j + 1] - s.desc.points[j]).norm();
        const double floor = std::min(0.01 * initial, s.rest_length[j]);
        const double next = s.rest_length[j] - left;
        if (next > floor || k + 1 == m) {  // the last segment is never wound up: it stays at its floor
            resize(s, j, std::max(next, floor), mode);
            return;
        }
        left -= s.rest_length[j] - floor;
        resize(s, j, floor, mode);
        const std::size_t p = particle(k + 1);
        s.hold[p].kind = detail::ParticleHold::Kind::Pin;
        s.hold[p].point = drum;
        s.hold[p].body = RigidId{};
        s.x[p] = drum;
        s.v[p].setZero();
        ++k;
    }
}

}  // namespace tearables
