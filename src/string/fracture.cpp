// The material stage: response to the estimated tension (Strings Sec. 5.3-5.4; Yarn
// Sec. 3.3-3.4).
//
// Stress sigma = T / (pi r0^2) (Strings Eq. 8, engineering stress on the original
// section). The tensile curve is bilinear: strain sigma/E up to the yield stress, then
// yield/E + (sigma - yield)/E_p (Strings Sec. 5.1). Choices where the papers are vague:
//  - L_max = L_rest (1 + sigma/E) (Strings Sec. 5.4, Yarn Sec. 3.3): an unloaded rope is
//    inextensible, a loaded one lengthens as its modulus says. The limiter meets it through
//    the compliance L_rest / (E A) (strain_limit.cpp); L_max is kept for the trace.
//  - Past yield the peak stress sets a permanent strain eps_perm = eps_curve(peak) - peak/E
//    (unloading parallel to the elastic line); rest length L0 (1 + eps_perm) (Yarn Sec. 3.4).
//  - With StringDesc::yield_in_solve the flow is solved with the strain limit
//    (plastic_spring.hpp) and this is its return mapping: the peak stress is the force the
//    solve ended with, f / A0, not the tension estimate (which a heavy load's oscillation
//    in the estimate would overshoot); tears still read the tension.
//  - The radius keeps the segment's volume: r = r0 sqrt(L0 / L_max).
//  - A segment at its rupture stress breaks (if the string is tearable): removed, its
//    particles stay, a Tear event. Only the most overloaded segment of a string breaks per
//    step (a uniform rope would shatter at once; after the first tear the rest is unloaded).
#include "base/constants.hpp"
#include "base/lanes.hpp"
#include "base/thread_pool.hpp"
#include "sim/material_curve.hpp"
#include "string/string_state.hpp"

#include <algorithm>
#include <cmath>

namespace tearables::detail {

namespace {

Event makeEvent(const StringState& s, StringId id, EventType type, EventCause cause, int segment, double stress,
                const StepContext& ctx) {
    Event e;
    e.type = type;
    e.cause = cause;
    e.string = id;
    e.object = s.desc.name;
    e.segment = segment;
    e.stress = stress;
    e.time = ctx.time;
    e.step = ctx.step;
    return e;
}

}  // namespace

void respondMaterial(StringState& s, StringId id, const StepContext& ctx, std::vector<Event>& events) {
    const std::size_t m = s.segments();
    const double r0 = s.desc.radius;
    const double area0 = kPi * r0 * r0;
    // The tensile response, on the pool for a long string: each range keeps its own most
    // overloaded segment and yield events, merged in range order as one loop would have.
    struct Worst {
        int index = -1;
        double ratio = 0.0, stress = 0.0;
        EventCause cause = EventCause::Tension;
        /// Takes segment j where its ratio is the largest yet (strictly: the first of equals).
        void offer(int j, double r, double st, EventCause c) {
            if (!(r > ratio)) return;
            index = j;
            ratio = r;
            stress = st;
            cause = c;
        }
    };
    Worst worst_part[kMaxRanges];
    std::vector<Event> part_events[kMaxRanges];  // the ranges after the first (the first writes to events)
    forRanges(ctx.pool, m, kParallelItems, [&](std::size_t j0, std::size_t j1, std::size_t part) {
        Worst& worst = worst_part[part];
        std::vector<Event>& range_events = part == 0 ? events : part_events[part];
        // Segment j at engineering stress `stress`: a tear candidate (false: its geometry
        // stays), or its yield and hardening; true where its geometry follows the stress.
        const auto yieldAt = [&](std::size_t j, double stress, double solved) {
            if (s.broken[j]) return false;
            const SegmentMaterial& mat = s.material[j];
            if (s.desc.tearable && stress >= mat.rupture) {
                // Tear the most overloaded segment only: once it is gone the others are
                // unloaded, and the next step's tension says whether they still tear.
                worst.offer(static_cast<int>(j), stress / mat.rupture, stress, EventCause::Tension);
                return false;
            }
            // The stress the segment flows by: the solve's (its return mapping) or the estimate.
            // An unconverged solve's forces are not a state of the material (a segment the
            // last iteration left on the wrong branch reads far past its knee): its flow
            // waits for the next step's solve, which starts from the peak kept here.
            const double flowing = s.scratch.plastic_in_solve ? (s.scratch.strain_converged ? solved : 0.0) : stress;
            if (flowing > mat.yield) {
                if (!s.yielded[j]) {
                    s.yielded[j] = 1;
                    range_events.push_back(makeEvent(s, id, EventType::Yield, EventCause::Tension, static_cast<int>(j), flowing, ctx));
                }
                // A string that cannot tear stops flowing at its rupture stress (otherwise
                // the thinning of a yielding segment would run away).
                const double flow = std::min(flowing, mat.rupture);
                if (flow > s.peak_stress[j]) {
                    s.peak_stress[j] = flow;
                    const double permanent = strainOnCurve(mat, flow) - flow / mat.young;
                    s.rest_length[j] = s.original_length[j] * (1.0 + permanent);
                }
            }
            return true;
        };
        // The geometry two segments at a time, divisions and root in lanes (the same bits;
        // lanes of segments that keep their geometry are dropped). Engineering stress, as
        // stress-strain curves and rupture stresses are measured; the thinned radius is geometry.
        for (std::size_t j = j0; j < j1; j += 2) {
            const std::size_t k = j + 1 < j1 ? j + 1 : j;  // an odd count: the last one twice
            const Lanes2 stress = Lanes2{std::max(0.0, s.tension[j]), std::max(0.0, s.tension[k])} / area0;
            const Lanes2 solved = Lanes2{s.spring_force[j], s.spring_force[k]} / area0;
            const bool follow[2] = {yieldAt(j, stress[0], solved[0]), k != j && yieldAt(k, stress[1], solved[1])};
            if (!follow[0] && !follow[1]) continue;
            const Lanes2 rest{s.rest_length[j], s.rest_length[k]};
            const Lanes2 young{s.material[j].young, s.material[k].young};
            const Lanes2 max_length = rest * (1.0 + stress / young);
            const Lanes2 radius = r0 * sqrtLanes(Lanes2{s.original_length[j], s.original_length[k]} / max_length);
            const Lanes2 compliance = rest / (young * area0);  // engineering: E on the original section
            for (int lane = 0; lane < 2; ++lane) {
                if (!follow[lane]) continue;
                const std::size_t i = lane == 0 ? j : k;
                s.max_length[i] = max_length[lane];
                s.radius[i] = radius[lane];
                s.compliance[i] = compliance[lane];
            }
        }
    });
    Worst worst;
    for (std::size_t part = 0; part < kMaxRanges; ++part) {
        if (part > 0) events.insert(events.end(), part_events[part].begin(), part_events[part].end());
        worst.offer(worst_part[part].index, worst_part[part].ratio, worst_part[part].stress, worst_part[part].cause);
    }
    // Torsion (Strings Sec. 5.4, Eq. 11 with the division by length): per joint between
    // segments k and k+1, gamma = r (theta_{k+1} - theta_k) / l. Past the yield strain the
    // joint's rest twist grows (hardening as in tension, unloading parallel to G); a
    // segment whose torsional strain (the mean of its joints') reaches rupture breaks.
    const std::size_t joints = s.rest_twist.size();
    // Joints, then segments, in ranges on the pool as above (events and the most overloaded
    // segment merged in range order).
    for (std::vector<Event>& e : part_events) e.clear();
    forRanges(ctx.pool, joints, kParallelItems, [&](std::size_t k0, std::size_t k1, std::size_t part) {
        std::vector<Event>& range_events = part == 0 ? events : part_events[part];
        for (std::size_t k = k0; k < k1; ++k) {
            if (s.broken[k] || s.broken[k + 1]) continue;
            // An untwisted joint (most of a rope that nothing twists): zero strain, without
            // the two divisions (r 0 / l is a zero, and its magnitude is what is kept).
            if (s.twist[k + 1] - s.twist[k] == 0.0 && s.rest_twist[k] == 0.0) {
                s.joint_strain[k] = 0.0;
                continue;
            }
            const double l = 0.5 * (s.rest_length[k] + s.rest_length[k + 1]);
            const double r = 0.5 * (s.radius[k] + s.radius[k + 1]);
            const double total = r * (s.twist[k + 1] - s.twist[k]) / l;
            const double elastic = total - r * s.rest_twist[k] / l;
            const SegmentMaterial& mat = s.material[k];
            if (std::abs(elastic) > mat.torsion_yield) {
                if (!s.torsion_yielded[k]) {
                    s.torsion_yielded[k] = 1;
                    range_events.push_back(
                        makeEvent(s, id, EventType::Yield, EventCause::Torsion, static_cast<int>(k), std::abs(total), ctx));
                }
                const double strain = std::min(std::abs(total), mat.torsion_rupture);
                if (strain > s.torsion_peak[k]) {
                    s.torsion_peak[k] = strain;
                    const double stress = mat.shear_modulus * mat.torsion_yield + mat.torsion_plastic * (strain - mat.torsion_yield);
                    const double permanent = strain - stress / mat.shear_modulus;
                    s.rest_twist[k] = std::copysign(permanent, total) * l / r;
                }
            }
            s.joint_strain[k] = std::abs(total);
        }
    });
    for (std::size_t part = 1; part < kMaxRanges; ++part) events.insert(events.end(), part_events[part].begin(), part_events[part].end());
    if (s.desc.tearable && joints > 0) {
        Worst torsion_part[kMaxRanges];
        forRanges(ctx.pool, m, kParallelItems, [&](std::size_t j0, std::size_t j1, std::size_t part) {
            Worst& best = torsion_part[part];
            for (std::size_t j = j0; j < j1; ++j) {
                if (s.broken[j]) continue;
                double sum = 0.0;
                int count = 0;
                if (j > 0 && !s.broken[j - 1]) sum += s.joint_strain[j - 1], ++count;
                if (j < joints && !s.broken[j + 1]) sum += s.joint_strain[j], ++count;
                if (count == 0 || sum == 0.0) continue;  // no torsional strain: ratio 0
                const double gamma = sum / count;
                const double ratio = gamma / s.material[j].torsion_rupture;
                if (ratio >= 1.0) best.offer(static_cast<int>(j), ratio, gamma, EventCause::Torsion);
            }
        });
        for (const Worst& best : torsion_part) worst.offer(best.index, best.ratio, best.stress, best.cause);
    }
    if (worst.index >= 0) {
        s.broken[worst.index] = 1;
        s.tension[worst.index] = 0.0;
        events.push_back(makeEvent(s, id, EventType::Tear, worst.cause, worst.index, worst.stress, ctx));
    }
}

}  // namespace tearables::detail
