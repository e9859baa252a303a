// A segment's spring past yield inside the strain-limit solve (StringDesc::yield_in_solve;
// docs/yield.md has the derivation and the measurements).
//
// The solve's spring is k c, k = E A0 / L the elastic stiffness (engineering: E on the
// original section) and c the effective stretch (Kelvin-Voigt, strain_limit.cpp). On the
// bilinear curve (Strings Sec. 5.1) a segment loaded past its current yield force F_y =
// sigma_peak A0 (sigma_peak >= yield: hardening raised it) follows the plastic slope
// dsigma/deps = E_p, a stiffness E_p A0 / L0 on the original length L0. Per k, with
// r = E_p L / (E L0) and c_y = F_y / k:
//
//   f(c) / k = c                         c <= c_y       (elastic)
//            = c_y + r (c - c_y)         c >  c_y       (plastic)
//            = f_u / k + (c - c_u)       c >  c_u       (an untearable string past its
//                                                       rupture force F_u stops flowing,
//                                                       as fracture.cpp caps it: elastic)
//
// with c_u = c_y + (F_u - F_y) / (k r). f is continuous and nondecreasing, so the energy
// psi(c) = int_0^c f is convex and C1: the Newton solve and its line search keep their
// guarantees with the tangent stiffness r k on the plastic branch. The return mapping
// (fracture.cpp) then sets the rest length from the force the solve ended with, so the
// next step starts on the elastic line through that point: no slack segment, no spike.
#pragma once

#include "base/constants.hpp"
#include "string/string_state.hpp"

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <limits>

namespace tearables::detail {

/// Where segment j's spring is at effective stretch c >= 0: its force over k (an
/// equivalent elastic stretch, m), its tangent over k, and its branch (1 elastic,
/// 2 plastic, 3 past rupture; 1 also where the string does not yield in the solve).
struct SpringBranch {
    double stretch;
    double slope;
    std::uint8_t branch;
};

/// Segment j's yield stretch c_y = F_y / k = sigma_peak A0 L / (E A0) (m; see the file's
/// header): three products, what a segment below yield costs.
[[gnu::always_inline]] inline double yieldStretch(const StringState& s, std::size_t j) {
    return s.peak_stress[j] * (kPi * s.desc.radius * s.desc.radius) * s.compliance[j];
}

/// The rest of segment j's knee past yield: the plastic ratio r and the rupture stretch
/// f_u / k (+inf where the string can tear: it tears there instead of hardening on).
struct PlasticKnee {
    double ratio, rupture_stretch;  ///< 1, m
};

inline PlasticKnee plasticKnee(const StringState& s, std::size_t j, double yield_stretch) {
    const SegmentMaterial& mat = s.material[j];
    PlasticKnee knee;
    knee.ratio = mat.plastic_modulus / mat.young * s.rest_length[j] / s.original_length[j];
    knee.rupture_stretch = s.desc.tearable ? std::numeric_limits<double>::infinity()
                                           : std::max(mat.rupture / s.peak_stress[j] * yield_stretch, yield_stretch);
    return knee;
}

/// Segment j's spring at effective stretch c >= 0 (elastic unless this step's solve takes
/// the plastic branch, StringScratch::plastic_in_solve).
[[gnu::always_inline]] inline SpringBranch springBranch(const StringState& s, std::size_t j, double c) {
    if (!s.scratch.plastic_in_solve) return {c, 1.0, 1};
    const double cy = yieldStretch(s, j);
    if (!(c > cy)) return {c, 1.0, 1};
    const PlasticKnee knee = plasticKnee(s, j, cy);
    const double plastic = cy + knee.ratio * (c - cy);
    if (!(plastic > knee.rupture_stretch)) return {plastic, knee.ratio, 2};
    const double c_u = cy + (knee.rupture_stretch - cy) / knee.ratio;
    return {knee.rupture_stretch + (c - c_u), 1.0, 3};
}

/// psi(c) / k: segment j's spring energy over its stiffness at effective stretch c >= 0.
inline double springEnergyOverStiffness(const StringState& s, std::size_t j, double c) {
    if (!s.scratch.plastic_in_solve) return 0.5 * c * c;
    const double cy = yieldStretch(s, j);
    if (!(c > cy)) return 0.5 * c * c;
    const PlasticKnee knee = plasticKnee(s, j, cy);
    const double c_u = knee.rupture_stretch == std::numeric_limits<double>::infinity()
                           ? std::numeric_limits<double>::infinity()
                           : cy + (knee.rupture_stretch - cy) / knee.ratio;
    const double plastic_end = std::min(c, c_u);
    const double dp = plastic_end - cy;
    double e = 0.5 * cy * cy + cy * dp + 0.5 * knee.ratio * dp * dp;
    if (c > c_u) {
        const double du = c - c_u;
        e += knee.rupture_stretch * du + 0.5 * du * du;
    }
    return e;
}

}  // namespace tearables::detail
