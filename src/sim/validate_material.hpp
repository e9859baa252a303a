// Validation of a Material, the one rule for every material that has one (strings, cloth
// yarns): each curve's points positive and within the physical ranges, rupture past yield.
#pragma once

#include "base/validate.hpp"
#include "tearables/material.hpp"

#include <string>
#include <string_view>

namespace tearables::detail {

// Physical ranges: wide enough for every real string or yarn (aerogel to osmium, foam to
// graphene), narrow enough that nothing derived from them under- or overflows.
constexpr double kMinStress = 1e-3, kMaxStress = 1e13;  // Pa (moduli and stresses)
constexpr double kMinStrain = 1e-9, kMaxStrain = 1e3;   // torsional strain

/// Throws InvalidInput naming the field under `path` ("material.tensile.rupture" for the
/// path "material").
inline void validateMaterial(const Material& m, std::string_view path) {
    const std::string p(path);
    const TensileCurve& t = m.tensile;
    requirePhysical(p + ".tensile.young", t.young, kMinStress, kMaxStress);
    requirePhysical(p + ".tensile.yield", t.yield, kMinStress, kMaxStress);
    requirePhysical(p + ".tensile.plastic_modulus", t.plastic_modulus, kMinStress, kMaxStress);
    requirePhysical(p + ".tensile.rupture", t.rupture, kMinStress, kMaxStress);
    if (!(t.rupture > t.yield))
        throw InvalidInput(p + ".tensile.rupture", "must be greater than yield (" + num(t.rupture) + " <= " + num(t.yield) + ")");
    const TorsionCurve& q = m.torsion;
    requirePhysical(p + ".torsion.modulus", q.modulus, kMinStress, kMaxStress);
    requirePhysical(p + ".torsion.yield", q.yield, kMinStrain, kMaxStrain);
    requirePhysical(p + ".torsion.plastic_modulus", q.plastic_modulus, kMinStress, kMaxStress);
    requirePhysical(p + ".torsion.rupture", q.rupture, kMinStrain, kMaxStrain);
    if (!(q.rupture > q.yield))
        throw InvalidInput(p + ".torsion.rupture", "must be greater than yield (" + num(q.rupture) + " <= " + num(q.yield) + ")");
    requireRange(p + ".variation", m.variation, 0.0, 0.5);
}

}  // namespace tearables::detail
