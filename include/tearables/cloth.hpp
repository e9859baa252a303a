// tearables: woven cloth made of tearable yarns (the Yarn paper extended to cloth).
//
// A cloth is a rectangular weave of vertices joined by yarn edges: warp yarns along the
// cloth's local x axis and weft yarns along its local z axis. Yarn edges are strain
// limited (inextensible below yield, as the material's modulus allows), carry a tension
// solved by momentum balance (Yarn Sec. 3.2, regularised least squares) and break at the
// material's rupture stress. Soft shear springs (cell diagonals) and bending springs
// (across two edges) keep the weave from collapsing in-plane and from crumpling; they
// are internal forces in the tension solve and never tear by themselves (they go with
// the yarns of their cell).
#pragma once

#include "tearables/material.hpp"
#include "tearables/sheet_attachment.hpp"
#include "tearables/types.hpp"

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace tearables {

/// Which yarn an edge belongs to.
enum class YarnKind : std::uint8_t {
    Warp,  ///< along local x: vertices (i, j) and (i + 1, j)
    Weft,  ///< along local z: vertices (i, j) and (i, j + 1)
};

/// A yarn edge weaker than the cloth's material: a flaw, or a notch where a tear is to
/// start. Its yield and rupture stresses (after the material's variation) are multiplied
/// by `strength`; its modulus is unchanged, so it carries the load its neighbours carry
/// until it yields or breaks first.
struct ClothWeakYarn {
    int i = 0;                      ///< column of the edge's first vertex, negative counts from the end
    int j = 0;                      ///< row of the edge's first vertex, negative counts from the end
    YarnKind kind = YarnKind::Warp; ///< warp: (i, j)-(i + 1, j), so i < last column; weft: (i, j)-(i, j + 1), so j < last row
    double strength = 0.5;          ///< factor on the yarn's yield and rupture stress, (0, 1]
};

/// Everything needed to create a cloth. Vertex (i, j) starts at
/// corner + orientation * (i * size[0] / (resolution[0] - 1), 0, j * size[1] / (resolution[1] - 1)):
/// the cloth lies in its local x-z plane, vertex (0, 0) at `corner`, or half the extent
/// ((resolution - 1) times the spacing) back from `center` along each local axis. Its flat
/// index is j * resolution[0] + i, as a paper sheet's. A resolution of 1 along one axis
/// makes a single yarn (a chain).
struct ClothDesc {
    std::string name;                     ///< for events and traces; may be empty
    /// Where the cloth lies (docs/SCENE_FORMAT.md, "Words"): give `center` (its centre) or
    /// `corner` (where vertex (0, 0), the local -x -z corner, lies), not both; neither puts its
    /// centre at (0, 1, 0). m, each coordinate in [-1e6, 1e6].
    std::optional<Vec3> center;
    std::optional<Vec3> corner;           ///< see `center`
    std::array<double, 2> size{1.0, 1.0}; ///< extent along local x and z, m, > 0 (ignored along an axis of resolution 1); every vertex within 1e6 m per axis
    std::array<int, 2> resolution{21, 21};///< vertices along local x and z, each 1..2000, at least 2 vertices in all
    Quat orientation = Quat::Identity();  ///< local to world, non-zero (normalised on creation)
    /// Areal density of the cloth, kg/m^2, [0, 1e6]: each vertex weighs its share of the area
    /// (a quarter cell per corner of a cell). Exactly one of areal_density and density must
    /// be > 0; a single yarn (resolution 1 along an axis) needs density.
    double areal_density = 0.1;
    /// Density of the yarn's fibre, kg/m^3, [0, 1e6]: each yarn edge weighs density * pi r^2 * length,
    /// half to each end. Used when areal_density is 0.
    double density = 0.0;
    double yarn_radius = 2.5e-4;          ///< m, > 0: stress = T / (pi r^2); also the contact radius of the vertices
    Material material;                    ///< the yarn's tensile curve (torsion is not used by cloth, but validated)
    double lambda = 1e-6;                 ///< Tikhonov parameter of the tension least squares, [0, 1] (relative to the mean diagonal of A^T A)
    /// Shear spring of each cell diagonal: force per unit strain, N, [0, 1e9] (a loose weave
    /// shears easily; the yarns carry the load).
    double shear_stiffness = 0.01;
    /// Bending spring across two consecutive edges of a yarn: force per unit strain, N, [0, 1e9].
    double bending_stiffness = 0.001;
    double damping = 0.0;                 ///< linear velocity damping, 1/s, [0, 1000]
    /// Viscoplastic time of the yarns, s, [0, 10]: past yield the rest length approaches
    /// the curve's permanent strain with this time constant (0 = at once). Yarn Sec. 3.4:
    /// a slow pull lets the yarn flow and lengthen before it breaks; a fast pull breaks it
    /// after less plastic lengthening.
    double plastic_time = 0.0;
    bool tearable = true;                 ///< yarns break where their stress reaches rupture
    /// Vertices glued to rigid bodies or pinned to world points at creation (at most one per
    /// vertex; `vertex` is the flat index above, negative counts from the end).
    std::vector<SheetAttachment> attachments;
    std::vector<ClothWeakYarn> weak_yarns;///< yarns weaker than `material` (at most one entry per yarn)
    std::uint64_t seed = 1;               ///< seeds the per-edge material variation

    /// Flat index of vertex (i, j); negative i, j count from the end. Throws InvalidInput("vertex").
    int vertex(int i, int j) const;
    /// Number of vertices.
    int vertexCount() const { return resolution[0] * resolution[1]; }
};

/// Throws InvalidInput naming the field when `desc` is not valid.
void validate(const ClothDesc& desc);

/// Read-only view of a cloth's state, valid until the next step or change.
struct ClothView {
    const std::vector<Vec3>* positions = nullptr;     ///< per vertex, m
    const std::vector<Vec3>* velocities = nullptr;    ///< per vertex, m/s
    const std::vector<double>* masses = nullptr;      ///< per vertex, kg
    const std::vector<std::array<std::uint32_t, 2>>* edges = nullptr;  ///< per yarn edge, its two vertices (fixed; torn edges stay listed)
    const std::vector<YarnKind>* kinds = nullptr;     ///< per yarn edge
    const std::vector<double>* tension = nullptr;     ///< per yarn edge, N (least squares; 0 where broken; may be slightly negative)
    const std::vector<double>* rest_length = nullptr; ///< per yarn edge, m (grows with plasticity)
    const std::vector<double>* max_length = nullptr;  ///< per yarn edge, strain limit L_max = L_rest (1 + sigma / E), m
    const std::vector<std::uint8_t>* broken = nullptr;///< per yarn edge, 1 = torn
    std::array<int, 2> resolution{0, 0};              ///< vertices along local x and z
    double yarn_radius = 0.0;                         ///< m
    double tension_residual = 0.0;                    ///< |A T - b| / |b| of the last tension solve (0 when b = 0)
    int tension_iterations = 0;                       ///< iterated-Tikhonov refinements of the last solve
    bool frozen = false;                              ///< stopped after a non-finite state
    std::size_t vertexCount() const { return positions->size(); }
    std::size_t edgeCount() const { return edges->size(); }
};

/// The faces a cloth shows the air (for addFaceDrag, tearables/paper.hpp): each cell of
/// the weave whose four yarns are intact, as two triangles, counter-clockwise seen from the
/// cloth's local +y; a cell with a torn yarn lets the air through.
std::vector<std::array<std::uint32_t, 3>> clothFaces(const ClothView& view);

}  // namespace tearables
