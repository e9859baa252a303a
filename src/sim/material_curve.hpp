// The tensile stress-strain curve shared by strings and cloth yarns (Strings Sec. 5.1,
// Yarn Sec. 3.3-3.4): bilinear, elastic slope E up to yield, then the plastic slope.
#pragma once

#include <random>

namespace tearables::detail {

/// Per-segment material constants after random variation (Strings, Sec. 7).
struct SegmentMaterial {
    double young, yield, plastic_modulus, rupture;                  ///< tensile, Pa
    double shear_modulus, torsion_yield, torsion_plastic, torsion_rupture;  ///< torsion
};

/// `value` varied uniformly by up to +-`variation` of itself (Strings, Sec. 7: the
/// material constants of each segment vary at random).
inline double vary(std::mt19937_64& rng, double value, double variation) {
    if (variation <= 0.0) return value;
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    return value * (1.0 + variation * u(rng));
}

/// Total strain on the curve at `stress` (Pa).
inline double strainOnCurve(const SegmentMaterial& mat, double stress) {
    if (stress <= mat.yield) return stress / mat.young;
    return mat.yield / mat.young + (stress - mat.yield) / mat.plastic_modulus;
}

/// Permanent strain left after unloading from a peak `stress` past yield (unloading runs
/// parallel to the elastic line): eps_curve(peak) - peak / E.
inline double permanentStrain(const SegmentMaterial& mat, double stress) {
    return stress <= mat.yield ? 0.0 : strainOnCurve(mat, stress) - stress / mat.young;
}

}  // namespace tearables::detail
