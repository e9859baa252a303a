// tearables: paper sheets (Kang and Cho, "Interactive paper animation with breakable hinge
// springs", referred to as *Paper*): a stiff mass-spring triangle mesh integrated by
// approximate implicit Euler with Jacobi iterations, whose compressed springs break into
// creases that the sheet keeps, whose folded edges become hinges, and which tears where it
// is stretched past its rupture point.
#pragma once

#include "tearables/sheet_attachment.hpp"
#include "tearables/types.hpp"

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace tearables {

/// What holds a vertex of a sheet at creation: the same as a cloth's (tearables/sheet_attachment.hpp).
using PaperAttachment = SheetAttachment;

/// How the sheet's stiff springs are integrated.
enum class PaperIntegrator {
    Implicit,  ///< Paper Sec. III.A: (M - h^2 J) dv = h f, solved as `solver` says (the default)
    Explicit,  ///< semi-implicit (symplectic) Euler: only to show that it diverges on stiff paper
};

/// How the implicit step's linear system (M - h C_v - h^2 J) dv = h (f + h J v) is solved.
enum class PaperSolver {
    Paper,              ///< Paper Eq. 6: `jacobi_iterations` weighted Jacobi sweeps, whatever the residual (the
                        ///< default): cheap, and soft where a sheet is loaded (the sweeps reach a few vertices).
                        ///< A sheet with no held vertex then gets the uniform velocity that leaves its momentum
                        ///< exact (the sweeps' residual summed; a translation stretches no spring)
    ConjugateGradient,  ///< block-Jacobi preconditioned conjugate gradients to `tolerance` (relative residual),
                        ///< warm-started from the last step's dv: the answer does not depend on an iteration
                        ///< count, but a stiff sheet's system is ill-conditioned and takes hundreds of
                        ///< iterations a step (BENCHMARKS.md, BM_PaperStepSolver)
    Multigrid,          ///< the same conjugate gradients to `tolerance`, preconditioned by a smoothed-aggregation
                        ///< multigrid V-cycle on the springs' graph (docs/paper-solver.md): tens of iterations
                        ///< where block-Jacobi takes hundreds; the aggregates follow creases and tears
};

/// How a sheet's edge tensions (the stress that tears it) are estimated.
enum class PaperTension {
    Stretch,   ///< the spring's own force k (l - l0): exact for this mass-spring model, O(edges)
    Momentum,  ///< Yarn Sec. 3.2: the tensions that explain each free vertex's momentum change,
               ///< by least squares regularised toward the spring force (lambda = 1e-6), solved
               ///< exactly (sparse Cholesky of the normal equations) every step
};

/// Describes a paper sheet: a rectangle at a resolution, or any triangle mesh.
struct PaperDesc {
    std::string name = "paper";          ///< for events and scenes
    // --- the rectangle (used when `vertices` is empty) ---
    /// Where the rectangle lies (docs/SCENE_FORMAT.md, "Words"): give `center` (its centre) or
    /// `corner` (where vertex (0, 0), the local -x -z corner, lies), not both; neither puts its
    /// centre at (0, 1, 0). m, each coordinate in [-1e6, 1e6].
    std::optional<Vec3> center;
    std::optional<Vec3> corner;          ///< see `center`
    Quat orientation = Quat::Identity(); ///< the sheet lies in its local x-z plane; non-zero (normalised)
    double size[2] = {0.21, 0.297};      ///< extent along local x and z, m, each > 0; every vertex within 1e6 m per axis
    int resolution[2] = {22, 30};        ///< vertices along local x and z, each 2..1024; vertex (i, k) is k * resolution[0] + i,
                                         ///< at corner + orientation * (i size[0] / (resolution[0] - 1), 0, k size[1] / (resolution[1] - 1))
    // --- or any triangle mesh (used when non-empty) ---
    std::vector<Vec3> vertices;                          ///< rest positions, m, finite
    std::vector<std::array<std::uint32_t, 3>> triangles; ///< counter-clockwise seen from the normal; non-degenerate, a manifold
    // --- material ---
    double areal_density = 0.08;         ///< mass per area, kg/m^2 (office paper: 0.08), [1e-9, 1e6]: the sheet weighs areal_density * its area
    double stiffness = 5e3;              ///< N/m, spring constant of the edges, (0, 1e12]. In a 2-D lattice this is also the
                                         ///< sheet's membrane stiffness, so it does not change with the resolution
    double bending = 0.05;               ///< bending springs' stiffness as a fraction of `stiffness`, [0, 1]
    double damping = 0.01;               ///< s, stiffness-proportional (Rayleigh) damping: c = damping * k per spring, [0, 1]
    PaperSolver solver = PaperSolver::Paper;  ///< how the implicit step's system is solved
    double tolerance = 1e-6;             ///< ConjugateGradient and Multigrid: stop when |b - W dv| <= tolerance |b|, [1e-12, 1e-1]
    int jacobi_iterations = 8;           ///< Paper: Jacobi iterations of the implicit solve (Paper Eq. 6), 1..256
    PaperIntegrator integrator = PaperIntegrator::Implicit;
    // --- breakable hinge springs (Paper Sec. III.B-C) ---
    double phi = 1.0;                    ///< fragility exponent of P = (1 - l/l0)^phi, (0, 1000] (large = rubbery, small = fragile)
    double psi = 0.5;                    ///< lift of a crease vertex, h = psi/2 sqrt(l0^2 - l^2), [0, 4] (area conservation)
    double hinge_threshold = 0.5;        ///< a hinge spring is inserted across an edge when its opposite vertices come
                                         ///< closer than this fraction of their rest distance, [0, 1)
    bool breakable = true;               ///< springs break under compression and edges fold into hinges
    // --- tearing (beyond Paper) ---
    bool tearable = false;               ///< the sheet separates where an edge is stretched past rupture_stretch
    double rupture_stretch = 0.02;       ///< relative stretch at which an edge tears, (0, 100]: l/l0 - 1, or with
                                         ///< Momentum tension the equivalent T / (k l0)
    PaperTension tension = PaperTension::Stretch;  ///< how edge tensions are estimated
    // --- collision and the rest ---
    double thickness = 1e-3;             ///< m, (0, 1]: vertices collide with rigid bodies as spheres of half this
    double friction = 0.5;               ///< Coulomb coefficient against rigid bodies, [0, 100] (combined with the body's: max)
    std::uint64_t seed = 1;              ///< seeds the sheet's random generator (breaking)
    /// Vertices glued to rigid bodies or pinned to world points at creation (at most one per
    /// vertex; `vertex` is gridVertex(i, k) or a mesh's index, negative counts from the end).
    std::vector<SheetAttachment> attachments;

    /// Vertex index of the rectangle's grid point (i along x, k along z).
    int gridVertex(int i, int k) const { return k * resolution[0] + i; }
};

/// Throws InvalidInput naming the field when `desc` is not valid.
void validate(const PaperDesc& desc);

/// What a spring of a sheet is.
enum class PaperSpringKind : std::uint8_t {
    Structural,  ///< an edge of the mesh (breakable under compression when the sheet is)
    Bending,     ///< across an edge, between the two opposite vertices (retired when it becomes a hinge)
    Auxiliary,   ///< unbreakable: keeps a broken spring's compressed length (the crease's memory)
    Hinge,       ///< unbreakable: inserted across a folded edge, at the folded distance
};

/// One spring (a read-only view). Spring indices never change: springs are only appended,
/// and a broken, retired or torn spring keeps its slot with `broken` set.
struct PaperSpring {
    std::uint32_t a = 0, b = 0;   ///< vertex indices
    double rest = 0.0;            ///< rest length, m
    double stiffness = 0.0;       ///< N/m
    PaperSpringKind kind = PaperSpringKind::Structural;
    bool broken = false;          ///< no longer acts (broke into a crease, retired, or torn)
    std::uint32_t hinge[2] = {UINT32_MAX, UINT32_MAX};  ///< Bending/Hinge: the edge it spans
};

/// Counters of a sheet's damage.
struct PaperCounters {
    std::uint64_t creases = 0;   ///< springs broken under compression (vertices inserted)
    std::uint64_t hinges = 0;    ///< hinge springs inserted
    std::uint64_t tears = 0;     ///< vertices split by tearing
};

/// Wall time of the sheets' stages in a step, s.
struct PaperTimes {
    double solve = 0, collision = 0, tension = 0, positions = 0, crease = 0, tear = 0;
    double total() const { return solve + collision + tension + positions + crease + tear; }
};

/// Read-only view of a sheet, valid until the next step or change.
///
/// Stable indices: vertices and springs are only ever appended (never removed or
/// reordered), so an index once seen names the same vertex or spring for the life of the
/// sheet. A triangle split by a crease keeps its slot for one half and the other half is
/// appended; a tear renames one corner of the triangles on one side of the cut to the
/// new (appended) vertex.
struct PaperView {
    const std::vector<Vec3>* positions = nullptr;    ///< per vertex, m
    const std::vector<Vec3>* velocities = nullptr;   ///< per vertex, m/s
    const std::vector<double>* masses = nullptr;     ///< per vertex, kg (sum is the sheet's mass, always)
    const std::vector<std::array<std::uint32_t, 3>>* triangles = nullptr;  ///< counter-clockwise
    const std::vector<PaperSpring>* springs = nullptr;
    const std::vector<double>* tension = nullptr;    ///< per spring, N (structural springs; 0 for the others and broken ones)
    PaperCounters counters;
    double thickness = 0.0;                          ///< m
    bool frozen = false;                             ///< stopped after a non-finite state
    std::size_t vertexCount() const { return positions->size(); }
};

/// The lines along which a sheet is creased or folded, as pairs of vertex indices (for
/// drawing: the --png pictures and BulletWorld::debugDraw): each crease (a spring broken
/// under compression) as the new vertex's mesh edges across the broken spring, and each
/// hinge's folded edge.
std::vector<std::array<std::uint32_t, 2>> paperCreaseLines(const PaperView& view);

/// Air drag on a sheet, face by face (a flat plate's pressure drag): each triangle feels
/// F = 1/2 air_density drag_coefficient A (w . n) |w . n| n, with A its area, n its unit
/// normal and w = wind minus the mean velocity of its corners, a third on each corner;
/// a face edge-on to the wind feels nothing. Adds into `force` (resized to the vertex
/// count; per vertex, N). The scene format's wind uses air_density 1.2 kg/m^3 and
/// drag_coefficient 1.2, as for strings. Throws InvalidInput naming the argument when
/// wind is not finite, a coefficient is negative or not finite, the velocities are not
/// one per position, or a triangle names a missing vertex.
void addFaceDrag(const std::vector<Vec3>& positions, const std::vector<Vec3>& velocities,
                 const std::vector<std::array<std::uint32_t, 3>>& triangles, const Vec3& wind, double air_density,
                 double drag_coefficient, std::vector<Vec3>& force);

}  // namespace tearables
