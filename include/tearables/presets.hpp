// tearables: named material presets (thread, rubber cord, ropes, spaghetti, ...) with the
// geometry each usually comes in. Values and their sources: src/string/presets.cpp.
#pragma once

#include "tearables/material.hpp"
#include "tearables/types.hpp"

#include <string>
#include <vector>

namespace tearables {

/// A named material with the geometry it usually comes in.
///
/// `material` follows material.hpp: tensile stresses and moduli in Pa, torsional
/// modulus and plastic slope in Pa, torsional yield/rupture as the dimensionless surface
/// shear strain gamma = r * dtheta/ds. Stresses are engineering stresses over the full
/// circular cross-section pi * radius^2 (for ropes and threads the *apparent* values,
/// air between the fibres included), so pi * radius^2 * material.tensile.rupture is the
/// breaking load in N at the suggested radius.
struct MaterialPreset {
    const char* name;         ///< identifier, lower case with underscores ("nylon_rope"); unique
    const char* description;  ///< one line for people: what the material is and its typical size
    Material material;        ///< stress-strain curves; variation 1e-4 (Strings, Sec. 7)
    double radius;            ///< suggested cross-section radius, m, > 0
    double density;           ///< suggested density, kg/m^3, > 0 (apparent for fibre structures: mass per length / (pi r^2))
};

/// All presets, in a fixed order (thread, rubber_cord, nylon_rope, braided_rope,
/// spaghetti, steel_wire, fishing_line). The reference stays valid for the program's life.
const std::vector<MaterialPreset>& materialPresets();

/// The preset with this name (exact, case-sensitive match), or nullptr when there is none.
/// The pointer stays valid for the program's life.
const MaterialPreset* findMaterialPreset(const std::string& name);

/// The material of the preset with this name, exactly as a scene's
/// `"material": {"preset": name}` gives it (the scene loader calls this): the preset's
/// curves and variation; its suggested radius and density are in findMaterialPreset().
/// Throws InvalidInput("preset", "unknown material preset \"name\" (known: thread, ...)").
Material materialPreset(const std::string& name);

}  // namespace tearables
