// Named material presets, with where each number comes from: typical handbook and trade
// figures for a common grade, quoted from memory (no measurement behind this table, and
// not a specification); "estimate" marks a number we derived from others.
//
// Conventions (material.hpp, SCENE_FORMAT.md):
// - Tensile curve, bilinear (Strings Sec. 5.1): slope `young` up to `yield`, then
//   `plastic_modulus` up to `rupture`; engineering stress over pi r^2. Threads and ropes
//   have apparent values (breaking load / pi r^2, air between the fibres: packing ~0.6-0.7).
//   Strain at rupture = yield/young + (rupture - yield)/plastic_modulus.
// - Torsion curve: `modulus` is the shear modulus G (Pa); yield and rupture are surface
//   shear strains gamma = r dtheta/ds. All estimates: gamma_y = tau_y / G, tau_y = tensile
//   yield / sqrt(3) (von Mises); gamma_r of fibre structures from the outer fibres' helix,
//   sqrt(1 + gamma^2) = 1 + e_b (Hearle, Grosberg & Backer, "Structural Mechanics of Fibers,
//   Yarns and Fabrics"), of isotropic solids from simple shear, lambda - 1/lambda = gamma at
//   lambda = 1 + e_b, of fibre and wire a measured twist-to-break where known (at the preset);
//   plastic_modulus = (tau_r - tau_y) / (gamma_r - gamma_y), tau_r = tensile rupture / sqrt(3).
// - variation 1e-4: the 0.01 % per-segment spread of Strings Sec. 7.
#include "tearables/presets.hpp"

namespace tearables {

namespace {

MaterialPreset makePreset(const char* name, const char* description) {
    MaterialPreset p{name, description, Material{}, 0.0, 0.0};
    p.material.variation = 1e-4;  // Strings, Sec. 7: "a range of variation up to 0.01%"
    return p;
}

// Cotton-wrapped polyester core-spun sewing thread, "all-purpose" Tex 27 (~ 0.2 mm thick).
MaterialPreset thread() {
    MaterialPreset p = makePreset("thread", "cotton/polyester core-spun sewing thread, Tex 27, 0.2 mm thick");
    p.radius = 1.0e-4;  // m; Tex 27 all-purpose sewing thread is ~0.2-0.25 mm across (thread makers' size charts)
    p.density = 860.0;  // kg/m^3, apparent: 27 g/km / (pi (0.1 mm)^2) = 859 (Tex = g per km; solid PET 1380, cotton 1540)
    TensileCurve& t = p.material.tensile;
    t.young = 5e9;            // Pa, apparent; PET fibre initial modulus 10-14 GPa (Morton & Hearle, "Physical Properties
                              // of Textile Fibres"), x packing ~0.6 x twist obliquity -> ~5 GPa (estimate)
    t.yield = 1e8;            // Pa; PET fibres yield at ~2 % strain (Morton & Hearle): 5 GPa x 0.02
    t.plastic_modulus = 1.9e9;  // Pa; chosen to reach rupture at ~17 % strain: thread makers quote 14-20 % elongation at break
    t.rupture = 3.8e8;        // Pa; Tex 27 core-spun thread breaks at ~11-13 N (tenacity ~40-45 cN/tex, thread makers'
                              // data sheets): 12 N / (pi (0.1 mm)^2) = 3.8e8 -> breaking load 11.9 N
    TorsionCurve& q = p.material.torsion;
    q.modulus = 5e8;          // Pa; PET fibre torsional (shear) modulus ~0.8-0.9 GPa (Morton & Hearle) x packing ~0.6 (estimate)
    q.yield = 0.12;           // (1e8 / sqrt 3) / 5e8 = 0.115, estimate from shear yield strength / G
    q.plastic_modulus = 3.3e8;  // Pa; (2.19e8 - 6e7) / (0.60 - 0.12), estimate (see top)
    q.rupture = 0.60;         // helix: sqrt(1.167^2 - 1) = 0.60, estimate; single PET fibres take more (breaking twist
                              // angle 42-59 deg, tan = 0.9-1.7, Morton & Hearle)
    return p;
}

// Solid natural-rubber cord, 4 mm.
MaterialPreset rubberCord() {
    MaterialPreset p = makePreset("rubber_cord", "solid natural-rubber cord, 4 mm thick (hyperelastic; bilinear fit is crude)");
    p.radius = 2.0e-3;  // m; 4 mm rubber cord, a common stock size
    p.density = 950.0;  // kg/m^3; NR gum vulcanizate 920-930, lightly filled ~950-1000 (rubber handbooks, e.g. Mark, Erman &
                        // Roland, "The Science and Technology of Rubber")
    // Rubber is hyperelastic (an S-shaped curve), elastic to near break, with no true yield:
    // this bilinear fit only reproduces the rupture stress and the strain at break. The first
    // slope is a secant; "yield" sits at 500 % strain; the steeper second slope is the upturn.
    TensileCurve& t = p.material.tensile;
    t.young = 2.5e6;          // Pa; NR small-strain E 1-5 MPa (handbook range; E = 3G, G 0.4-1 MPa), secant to 500 % strain
    t.yield = 1.25e7;         // Pa; at 500 % strain (2.5 MPa x 5), fit point, not a material yield
    t.plastic_modulus = 5e6;  // Pa; upturn slope chosen to break at 650 % strain (NR elongation at break 500-700 %)
    t.rupture = 2.0e7;        // Pa; NR tensile strength 15-25 MPa (gum and filled vulcanizates; rubber handbooks)
                              // -> breaking load 251 N at 4 mm
    TorsionCurve& q = p.material.torsion;
    q.modulus = 8.3e5;        // Pa; G = E/3 (incompressible, Poisson 0.5): 2.5e6 / 3
    q.yield = 5.8;            // simple shear at the fit's yield stretch lambda = 6: 6 - 1/6 = 5.83, estimate
    q.plastic_modulus = 8.3e5;  // Pa; = G: neo-Hookean shear stress is linear in gamma, so the slope stays G (estimate)
    q.rupture = 7.4;          // simple shear at lambda = 7.5 (650 % strain): 7.5 - 1/7.5 = 7.37, estimate; in practice a
                              // twisted rubber cord coils up long before this
    return p;
}

// Three-strand nylon 6,6 rope, 12 mm (1/2 inch).
MaterialPreset nylonRope() {
    MaterialPreset p = makePreset("nylon_rope", "three-strand laid nylon 6,6 rope, 12 mm thick");
    p.radius = 6.0e-3;  // m; 12 mm, a common mooring/utility size
    p.density = 760.0;  // kg/m^3, apparent: 12-13 mm nylon 3-strand weighs ~0.09-0.1 kg/m (cordage tables, e.g. Cordage
                        // Institute CI 1303); solid nylon 6,6 is 1140 (packing ~0.67)
    // Rope-level (apparent) values: the library default Material (E 3 GPa, rupture 80 MPa) is
    // solid nylon 6,6 plastic; oriented fibre in a rope is stronger and the rope stretchier.
    TensileCurve& t = p.material.tensile;
    t.young = 1.5e9;          // Pa, apparent; nylon fibre E 3-5 GPa (Morton & Hearle) x packing ~0.67 x strand helix;
                              // nylon rope stretches ~3-5 % at 25 % of its breaking load (cordage makers' load-elongation
                              // charts): 6e7 / 0.04 = 1.5 GPa (estimate)
    t.yield = 6e7;            // Pa; ~25 % of breaking load: past it laid nylon rope keeps permanent elongation (working
                              // loads are kept at 10-20 % of MBS; cordage makers' guidance)
    t.plastic_modulus = 7e8;  // Pa; chosen to break at ~30 % elongation (nylon rope 25-40 % at break, cordage data)
    t.rupture = 2.4e8;        // Pa; 12 mm nylon 3-strand minimum breaking strength ~25-30 kN (Cordage Institute CI 1303 /
                              // makers' tables): 27 kN / (pi (6 mm)^2) = 2.4e8 -> breaking load 27 kN
    TorsionCurve& q = p.material.torsion;
    q.modulus = 3e8;          // Pa; nylon fibre shear modulus ~0.4-0.5 GPa (Morton & Hearle) x packing ~0.67 (estimate)
    q.yield = 0.12;           // (6e7 / sqrt 3) / 3e8 = 0.115, estimate from shear yield strength / G
    q.plastic_modulus = 1.5e8;  // Pa; (1.39e8 - 3.6e7) / (0.80 - 0.12), estimate (see top)
    q.rupture = 0.80;         // helix: sqrt(1.30^2 - 1) = 0.83, estimate
    return p;
}

// Double-braid polyester (PET) rope, 10 mm.
MaterialPreset braidedRope() {
    MaterialPreset p = makePreset("braided_rope", "double-braid polyester rope, 10 mm thick");
    p.radius = 5.0e-3;  // m; 10 mm, a common sheet/halyard size
    p.density = 870.0;  // kg/m^3, apparent: 10 mm polyester double braid weighs ~6.5-7 kg/100 m (rope makers' catalogues);
                        // 0.068 / (pi (5 mm)^2) = 866; solid PET 1380 (packing ~0.63)
    TensileCurve& t = p.material.tensile;
    t.young = 2.5e9;          // Pa, apparent; polyester braid stretches ~2.5-3 % at 25 % of breaking load (makers'
                              // load-elongation data): 7e7 / 0.028 = 2.5 GPa; PET fibre itself 10-14 GPa (estimate)
    t.yield = 7e7;            // Pa; ~25 % of breaking load, where braid construction stretch turns permanent (estimate)
    t.plastic_modulus = 1.9e9;  // Pa; chosen to break at ~14 % (polyester rope 12-15 % at break; lower than nylon)
    t.rupture = 2.8e8;        // Pa; 10 mm polyester double braid breaks at ~2,200-2,500 kgf (makers' catalogues):
                              // 22 kN / (pi (5 mm)^2) = 2.8e8 -> breaking load 22 kN
    TorsionCurve& q = p.material.torsion;
    q.modulus = 5e8;          // Pa; PET fibre shear modulus ~0.8-0.9 GPa (Morton & Hearle) x packing ~0.63 (estimate)
    q.yield = 0.08;           // (7e7 / sqrt 3) / 5e8 = 0.081, estimate from shear yield strength / G
    q.plastic_modulus = 2.6e8;  // Pa; (1.62e8 - 4e7) / (0.54 - 0.08), estimate (see top)
    q.rupture = 0.54;         // helix: sqrt(1.139^2 - 1) = 0.54, estimate
    return p;
}

// One strand of cooked spaghetti.
MaterialPreset spaghetti() {
    MaterialPreset p = makePreset("spaghetti", "one strand of cooked spaghetti, ~2.4 mm thick (food-rheology estimates)");
    p.radius = 1.2e-3;   // m; dry spaghetti n.5 is 1.7-1.9 mm, swelling to ~2.2-2.6 mm when cooked (pasta makers' data)
    p.density = 1100.0;  // kg/m^3; cooked pasta ~60 % water + starch/protein ~1450: 1 / (0.6/1000 + 0.4/1450) = 1140,
                         // less some entrapped air (estimate)
    // Cooked pasta, a soft viscoelastic gel whose tensile data vary with cooking time:
    // order-of-magnitude estimates from food-rheology measurements, not a data sheet.
    TensileCurve& t = p.material.tensile;
    t.young = 3e6;            // Pa; cooked spaghetti E ~1-5 MPa (food rheology measurements of cooked pasta), estimate
    t.yield = 5e4;            // Pa; gel yields early and flows (necks) before breaking: ~half the breaking stress, estimate
    t.plastic_modulus = 2e5;  // Pa; chosen so that the strand breaks at ~27 % stretch (estimate; cooked strands stretch
                              // visibly before snapping)
    t.rupture = 1e5;          // Pa; breaking stress ~0.1 MPa (food rheology measurements of cooked pasta; ~0.03-0.1 MPa
                              // reported) -> breaking load 0.45 N (a ~45 g weight)
    TorsionCurve& q = p.material.torsion;
    q.modulus = 1e6;          // Pa; G = E/3 (water-swollen gel, Poisson ~0.5), estimate
    q.yield = 0.03;           // (5e4 / sqrt 3) / 1e6 = 0.029, estimate from shear yield strength / G
    q.plastic_modulus = 6.2e4;  // Pa; (5.77e4 - 3e4) / (0.48 - 0.03), estimate (see top)
    q.rupture = 0.48;         // simple shear at lambda = 1.267: 1.267 - 1/1.267 = 0.48, estimate
    return p;
}

// Cold-drawn high-carbon steel wire, 1 mm, wire-rope grade 1770.
MaterialPreset steelWire() {
    MaterialPreset p = makePreset("steel_wire", "cold-drawn high-carbon steel wire (rope wire, grade 1770 MPa), 1 mm thick");
    p.radius = 5.0e-4;   // m; 1 mm wire
    p.density = 7850.0;  // kg/m^3; carbon steel 7850 (steel handbooks)
    TensileCurve& t = p.material.tensile;
    t.young = 2.0e11;         // Pa; carbon steel E 200-210 GPa, drawn wire ~195-205 GPa (steel handbooks)
    t.yield = 1.5e9;          // Pa; 0.2 % proof stress of cold-drawn patented wire ~80-90 % of tensile strength (wire
                              // standards, e.g. EN 10264 data)
    t.plastic_modulus = 1.5e10;  // Pa; chosen to break at ~2.5 % elongation (drawn high-carbon wire: 2-4 %)
    t.rupture = 1.77e9;       // Pa; tensile grade 1770 N/mm^2 (EN 10264-2 rope-wire grades 1570-2160)
                              // -> breaking load 1.39 kN at 1 mm
    TorsionCurve& q = p.material.torsion;
    q.modulus = 8.0e10;       // Pa; steel G 79-81 GPa (steel handbooks)
    q.yield = 0.011;          // (1.5e9 / sqrt 3) / 8e10 = 0.0108, estimate from shear yield strength / G
    q.plastic_modulus = 2.4e8;  // Pa; (1.02e9 - 8.8e8) / (0.60 - 0.011), estimate (see top): torque barely rises past yield
    q.rupture = 0.60;         // torsion test (ISO 7800) of rope wire: ~20-30 turns over a 100 d gauge length before
                              // breaking (EN 10264 minimum twist counts), gamma = pi N / 100 = 0.63-0.94; we take
                              // the low end (quoted from memory: estimate)
    return p;
}

// Nylon 6 monofilament fishing line, 0.30 mm.
MaterialPreset fishingLine() {
    MaterialPreset p = makePreset("fishing_line", "nylon monofilament fishing line, 0.30 mm (~5 kg test)");
    p.radius = 1.5e-4;   // m; 0.30 mm line
    p.density = 1140.0;  // kg/m^3; nylon 6 / 6,6 1130-1150 (polymer handbooks, e.g. MatWeb/Callister)
    TensileCurve& t = p.material.tensile;
    t.young = 2.5e9;          // Pa; nylon monofilament E ~1.5-3 GPa (oriented nylon; polymer/fibre handbooks), estimate
    t.yield = 1.2e8;          // Pa; yield near 5 % strain, where oriented nylon's curve flattens (estimate)
    t.plastic_modulus = 2.9e9;  // Pa; chosen to break at ~25 % stretch (monofilament 20-30 % at break, line makers' data)
    t.rupture = 7e8;          // Pa; 0.30 mm line rated ~5-7 kg (line makers' labels): 5 kg = 49 N / (pi (0.15 mm)^2)
                              // = 7e8 -> breaking load 49.5 N
    TorsionCurve& q = p.material.torsion;
    q.modulus = 4.5e8;        // Pa; oriented nylon fibre shear modulus ~0.4-0.5 GPa (Morton & Hearle), estimate
    q.yield = 0.15;           // (1.2e8 / sqrt 3) / 4.5e8 = 0.154, estimate from shear yield strength / G
    q.plastic_modulus = 4e8;  // Pa; (4.04e8 - 6.8e7) / (1.0 - 0.15), estimate (see top)
    q.rupture = 1.0;          // nylon fibre breaking twist angle 46-62 deg (Morton & Hearle): tan 46 deg = 1.0, low end
    return p;
}

}  // namespace

const std::vector<MaterialPreset>& materialPresets() {
    static const std::vector<MaterialPreset> presets = {
        thread(), rubberCord(), nylonRope(), braidedRope(), spaghetti(), steelWire(), fishingLine(),
    };
    return presets;
}

const MaterialPreset* findMaterialPreset(const std::string& name) {
    for (const MaterialPreset& p : materialPresets())
        if (name == p.name) return &p;
    return nullptr;
}

Material materialPreset(const std::string& name) {
    if (const MaterialPreset* p = findMaterialPreset(name)) return p->material;
    std::string known;
    for (const MaterialPreset& p : materialPresets()) known += (known.empty() ? "" : ", ") + std::string(p.name);
    throw InvalidInput("preset", "unknown material preset \"" + name + "\" (known: " + known + ")");
}

}  // namespace tearables
