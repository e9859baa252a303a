// tearables: material descriptors (Strings, Sec. 5.1: tensile and torsional stress-strain curves).
#pragma once

namespace tearables {

/// Tensile stress-strain curve, bilinear: elastic slope `young` up to `yield`, then
/// `plastic_modulus` up to `rupture` (Strings, Sec. 5.1, Fig. 3a). Stresses in Pa.
/// Defaults: a nylon rope (E 3 GPa; yield 40 MPa; rupture 80 MPa).
struct TensileCurve {
    double young = 3e9;            ///< Young's modulus, Pa, [1e-3, 1e13]
    double yield = 4e7;            ///< yield stress, Pa, [1e-3, 1e13]
    double plastic_modulus = 3e8;  ///< slope past yield, Pa, [1e-3, 1e13]
    double rupture = 8e7;          ///< rupture stress, Pa, > yield, at most 1e13
};

/// Torsional curve in torsional strain gamma = r * dtheta/ds (dimensionless; see
/// SCENE_FORMAT.md: Strings Eq. 11 with the division by length it lacks).
struct TorsionCurve {
    double modulus = 1e9;          ///< shear modulus, Pa, [1e-3, 1e13]
    double yield = 0.05;           ///< yield strain, [1e-9, 1e3]
    double plastic_modulus = 1e8;  ///< slope past yield, Pa, [1e-3, 1e13]
    double rupture = 0.1;          ///< rupture strain, > yield, at most 1e3
};

/// A string's material.
struct Material {
    TensileCurve tensile;   ///< tension behaviour
    TorsionCurve torsion;   ///< twist behaviour
    double variation = 1e-4;  ///< random relative variation per segment of the curve's points, [0, 0.5]
};

}  // namespace tearables
