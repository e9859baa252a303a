// Paper sheets: the state of one sheet and the kernels of its step, one file per stage
// (desc.cpp: validation and the rest mesh; implicit.cpp: forces and the Jacobi solve;
// contact.cpp: rigid bodies; hinge.cpp: breakable hinge springs; tear.cpp: tearing;
// mesh.cpp: topology helpers and the validity check). No Bullet here.
#pragma once

#include "linalg/supernodal.hpp"
#include "sim/hold.hpp"
#include "tearables/events.hpp"
#include "tearables/paper.hpp"
#include "tearables/world.hpp"

#include <algorithm>
#include <array>
#include <cstdint>
#include <random>
#include <string>
#include <vector>

namespace tearables::detail {

struct RigidTable;

/// v.assign(n, value), where a growing v takes half its capacity again: a sheet that
/// creases every step gains vertices and springs every step, and an exact assign would
/// allocate its per-vertex and per-entry arrays afresh at every step.
template <class T> void assignGrowing(std::vector<T>& v, std::size_t n, const typename std::vector<T>::value_type& value) {
    if (n > v.capacity()) v.reserve(std::max(n, v.capacity() + v.capacity() / 2));
    v.assign(n, value);
}

/// The couplings of springs in the implicit solve, seen from one of their vertices, four
/// row entries side by side (lanes 0-3, row entry j in lane j % 4 of block j / 4;
/// structure of arrays inside the block, so the Jacobi sweep works on two or four entries
/// at once): W_ij = -(iso I + along dir dir^T) (h c d d^T + h^2 K of implicit.cpp, with
/// K = k (d d^T + t (I - d d^T))): 44 bytes per entry instead of a 3x3 block and the spring.
struct JacobiQuad {
    double iso[4] = {0.0, 0.0, 0.0, 0.0};    ///< h^2 k t, kg
    double along[4] = {0.0, 0.0, 0.0, 0.0};  ///< h c k + h^2 k (1 - t), kg
    double dir_x[4] = {0.0, 0.0, 0.0, 0.0};  ///< unit, along the spring
    double dir_y[4] = {0.0, 0.0, 0.0, 0.0};
    double dir_z[4] = {0.0, 0.0, 0.0, 0.0};
    std::uint32_t other[4] = {0, 0, 0, 0};   ///< the spring's other vertex
};

/// A vertex's entry of a Jacobi iterate (implicit.cpp): a velocity change, m/s, x y z
/// padded to 32 aligned bytes, so that the AVX2 sweep loads a neighbour's in one load and
/// four of them are transposed into x, y and z lanes in registers.
struct alignas(32) JacobiEntry {
    double v[4] = {0.0, 0.0, 0.0, 0.0};  ///< x, y, z, and 0
    JacobiEntry() = default;
    explicit JacobiEntry(const Vec3& a) : v{a.x(), a.y(), a.z(), 0.0} {}
    Vec3 vec() const { return Vec3(v[0], v[1], v[2]); }
};

/// One coarse level of the paper's multigrid (multigrid.cpp): nodes of 3 unknowns each.
struct PaperMultigridLevel {
    /// Galerkin operator P^T A P of the level above, 3 N x 3 N, row-major; its pattern is
    /// built with the aggregates, its values every step. The three scalar rows of a node
    /// have the same columns, so block (I, J) starts at `base` and its row r at base + r stride.
    Eigen::SparseMatrix<double, Eigen::RowMajor> A;
    std::vector<std::uint32_t> diag_at;  ///< per node: value index of its diagonal block's (0, 0)
    std::vector<Mat3> diag_inv;          ///< per node: inverse of its diagonal block (block Gauss-Seidel)
    Eigen::VectorXd r, e, t;             ///< right-hand side, correction, scratch (3 N)
};

/// A term of a Galerkin product: coef times a source 3x3 block added into a target block
/// (value index of its (0, 0) entry and its row stride).
struct PaperGalerkinTerm {
    std::uint32_t target = 0, target_stride = 0;
    std::uint32_t source = 0, source_stride = 0;  ///< coarse levels only: the source block
    double coef = 0.0;
};

/// Smoothed aggregation multigrid for the implicit solve (multigrid.cpp): the aggregates
/// and prolongators depend on the live springs and held vertices only and are rebuilt when
/// they change; the coarse operators are recomputed every step.
struct PaperMultigrid {
    bool built = false;
    std::uint64_t rows_version = 0;      ///< PaperSheet::rows_version it was built for
    std::vector<std::uint8_t> fixed;     ///< the held flags it was built for
    /// prolong[l]: level l's nodes (rows; level 0 = vertices) from level l + 1's (columns),
    /// scalar weights (each weight times the 3x3 identity); a held vertex's row is empty.
    std::vector<Eigen::SparseMatrix<double, Eigen::RowMajor>> prolong;
    std::vector<PaperMultigridLevel> levels;  ///< levels[0] is unused (the fine level is matrix-free)
    /// Level 0 -> 1: per live spring (link order) + 1, its first term in spring_terms;
    /// per vertex + 1, its first term in mass_terms.
    std::vector<std::uint32_t> spring_term_start, mass_term_start;
    std::vector<PaperGalerkinTerm> spring_terms, mass_terms;
    std::vector<std::vector<PaperGalerkinTerm>> coarse_terms;  ///< [l]: level l -> l + 1, l >= 1
    Eigen::MatrixXd dense;               ///< the coarsest operator
    Eigen::LLT<Eigen::MatrixXd> dense_llt;
    bool dense_ok = false;               ///< its Cholesky succeeded this step (else it is smoothed only)
    std::vector<Vec3> t;                 ///< fine-level scratch (per vertex)
    int coarsest_sweeps = 0;             ///< > 0: the coarsest level is too large for a dense factor and is smoothed
};

/// One sheet. Vertices are structure of arrays; springs and triangles are appended only.
struct PaperSheet {
    PaperDesc desc;
    bool alive = true;
    /// The slot's generation (the id's): grows by one when the object is removed.
    std::uint32_t generation = 0;
    bool frozen = false;
    // per vertex (n)
    std::vector<Vec3> x;          ///< positions at the start of the step / after it, m
    std::vector<Vec3> x_pred;     ///< predicted positions of the step (collision query), m
    std::vector<Vec3> v;          ///< velocities, m/s
    std::vector<Vec3> force;      ///< user forces for the next step, N
    std::vector<double> mass;     ///< kg
    std::vector<ParticleHold> hold;
    std::vector<std::uint8_t> crack_tip;  ///< 1 where a tear's cut ends inside the sheet (tear.cpp)
    // topology
    std::vector<std::array<std::uint32_t, 3>> triangles;
    std::vector<PaperSpring> springs;
    /// Adjacency, kept up to date by the helpers of mesh.cpp (setCorner, addTriangle,
    /// addSpring, setSpringName): per vertex, the triangles that use it, and the springs
    /// that name it (as an end or as what they span). Topology changes look up only
    /// their neighbourhood, never the whole mesh.
    std::vector<std::vector<std::uint32_t>> vertex_triangles;
    std::vector<std::vector<std::uint32_t>> vertex_springs;
    /// Per spring: the largest compression 1 - l/l0 it has survived (breaking draws only
    /// against the increase, so the chance to have broken by compression c is c^phi
    /// whatever the time step).
    std::vector<double> survived;
    PaperCounters counters;
    std::mt19937_64 rng;
    double total_mass = 0.0;
    // solver scratch (sized to the mesh; grows only when the topology grows)
    std::vector<Mat3> diag_inv;   ///< per vertex, inverse of W_ii
    std::vector<Vec3> rhs;        ///< per vertex, h f + h^2 J v
    std::vector<JacobiEntry> dv, dv_next;  ///< per vertex, the Jacobi iterate (velocity change, m/s) and the next one
    /// Conjugate gradients (implicit.cpp, conjugateGradient): per vertex W_ii, the residual,
    /// the preconditioned residual, the search direction and W times it; and the last
    /// step's dv (the warm start, kept across steps).
    std::vector<Mat3> diag;
    std::vector<Vec3> cg_r, cg_z, cg_p, cg_q, cg_warm;
    int cg_iterations = 0;        ///< iterations of the last solve
    double cg_residual = 0.0;     ///< its relative residual |b - W dv| / |b|
    PaperMultigrid mg;            ///< PaperSolver::Multigrid's hierarchy (multigrid.cpp)
    // rows of the Jacobi gather (implicit.cpp, buildRows), rebuilt when the live springs change
    std::vector<std::array<std::uint32_t, 2>> link_ends;  ///< per live spring, in order: its vertices
    std::vector<std::array<std::uint32_t, 2>> link_slot;  ///< per live spring: its entries in the rows of a and b
    std::vector<std::uint32_t> vertex_link_start;  ///< per vertex + 1, first entry of its row (even: rows are padded to pairs)
    std::vector<JacobiQuad> row_quads;             ///< per four row entries, the springs' blocks and other vertices (a pad: zero)
    std::vector<Vec3> row_force;                   ///< per row entry, h f + h^2 K (v_other - v_this) on this vertex, N s
    std::vector<double> link_length;               ///< per spring, its length at the step's start if live, m (the tension reuses it)
    std::size_t row_vertices = 0;                  ///< vertex count the rows were built for
    std::size_t row_reach = 0;                     ///< largest |other - this| over the row entries (the sweeps' pipeline lag)
    std::uint64_t rows_version = 0;                ///< grows by one each time the rows are rebuilt
    std::vector<std::uint8_t> fixed;  ///< per vertex, its velocity is prescribed (pinned, glued)
    std::vector<Vec3> added_force;    ///< per vertex, the weight of the mass lent to it, N
    std::vector<Mat3> added_mass;     ///< per vertex, movable bodies' mass lent to it this step (contact normal, glue), kg
    std::vector<Vec3> v_start;        ///< per vertex, velocity at the step start (momentum balance)
    std::vector<double> tension;      ///< per spring, N (structural; 0 otherwise)
    /// Scratch of the momentum tension (tension.cpp), kept so that a running step does not
    /// allocate: per vertex its row flag, b_i and A T; per spring its unknown; per unknown
    /// its spring, direction and the conjugate gradients' vectors.
    struct TensionScratch {
        std::vector<std::uint8_t> row;
        std::vector<Vec3> b, image;
        std::vector<int> unknown;
        std::vector<std::uint32_t> springs;
        std::vector<Vec3> dir;
        std::vector<std::uint32_t> edge_start, edge_unknown;  ///< per row vertex + 1 / per entry: its unknowns
        std::vector<Vec3> edge_dir;              ///< per entry: the unit vector along the edge, away from the vertex
        std::vector<double> rhs, diagonal, solution, residual, z, direction, product;
        // The direct solve (tension.cpp): the normal matrix's pattern, built for the live
        // structural springs and their ends in `pattern_ends` (rebuilt when they change).
        std::vector<std::array<std::uint32_t, 3>> pattern_ends;  ///< per unknown: spring, a, b
        std::vector<std::array<std::uint32_t, 3>> seen_ends;     ///< the same, as the last step that changed them left them
        std::vector<int> column;                 ///< per unknown: its column (fill-reducing order)
        std::vector<std::uint32_t> incident_start;  ///< per vertex + 1: its entries in `incident`
        std::vector<int> incident;               ///< unknowns at the vertex (that name it as an end), signed: ~u where it is b
        std::vector<std::uint32_t> pair_start;   ///< per vertex + 1: its entries in `pair_value`
        std::vector<int> pair_value;             ///< per vertex, per pair (a, k <= a) of its incident unknowns: index into the values
        Eigen::SparseMatrix<double> normal;      ///< lower triangle of A^T A + lambda I, columns in `column` order
        SupernodalLLT factor;
        Eigen::VectorXd right;                   ///< right-hand side and solution, in column order
        int iterations = 0;       ///< the last solve's conjugate gradient iterations
        double residual_norm = 0.0;  ///< and its relative residual |rhs - N T| / |rhs| at the end
    } tension_scratch;

    std::size_t vertices() const { return x.size(); }
};

/// Per-step context of the sheets.
struct PaperStep {
    double h = 0.0;
    double inv_h = 0.0;
    Vec3 gravity = Vec3::Zero();
    double max_speed = 500.0;
    double time = 0.0;
    std::int64_t step = 0;
};

// --- desc.cpp ---
/// Builds a sheet from a validated descriptor (rest mesh, masses, springs). Attachments to
/// bodies are resolved by the caller (it knows the bodies).
PaperSheet buildSheet(const PaperDesc& desc);
/// The rest positions and triangles a descriptor describes (the rectangle or the mesh).
void restMesh(const PaperDesc& desc, std::vector<Vec3>& x, std::vector<std::array<std::uint32_t, 3>>& triangles);

// --- implicit.cpp ---
/// Forces and the velocity solve: Paper Sec. III.A (implicit) or explicit Euler. Writes
/// the new velocities into s.v and the predicted positions into s.x_pred.
void solveVelocities(PaperSheet& s, const RigidTable& rigids, const PaperStep& ctx);
/// Spring force on vertex a of a spring (b gets the opposite), N, damping included.
Vec3 springForce(const PaperSpring& sp, const Vec3& xa, const Vec3& xb, const Vec3& va, const Vec3& vb, double damping);

// --- multigrid.cpp ---
/// PaperSolver::Multigrid: (re)builds the aggregates when the rows or the held vertices
/// changed, then the coarse operators of this step's system. Needs the rows, s.diag,
/// s.diag_inv (inverted), s.mass, s.added_mass and s.fixed of the step.
void multigridSetup(PaperSheet& s);
/// z = V(r): one symmetric V-cycle on W z = r (held rows: r and z zero), the conjugate
/// gradient's preconditioner.
void multigridPrecondition(PaperSheet& s, const std::vector<Vec3>& r, std::vector<Vec3>& z);
/// y = W x on the free rows (y = 0 on a held row).
void applySystem(const PaperSheet& s, const std::vector<Vec3>& x, std::vector<Vec3>& y);

// --- contact.cpp ---
/// A vertex solved together with a share of a movable body's mass: along the contact
/// normal (projector n n^T) or fully (glue, projector I).
struct BodyCoupling {
    std::uint32_t vertex = 0;
    RigidId body;
    Mat3 lent = Mat3::Zero();       ///< the body's mass lent to the vertex, kg (n n^T scaled for a contact)
    Vec3 normal = Vec3::Zero();     ///< contact: unit, from the body toward the vertex; glue: zero
    Vec3 arm = Vec3::Zero();        ///< from the body's centre of mass to the vertex, m
    Vec3 body_velocity = Vec3::Zero();  ///< the body point's velocity before coupling, m/s
};
/// Before the solve: every glue to a movable body, and every contact with one that the
/// vertex is about to close, lends the vertex a share (1 / `count_of(body)`) of the body's
/// effective mass at that point (rotation included), and the vertex starts with the momentum-weighted common velocity. The stiff
/// sheet then carries the body implicitly (a light vertex alone cannot: its momentum is
/// too small to stop a box in a step, and the box would push through).
void coupleBodies(PaperSheet& s, const std::vector<PointContact>& contacts, const std::vector<double>& count_of,
                  const RigidTable& rigids, const PaperStep& ctx, std::vector<BodyCoupling>& out);
/// Counts, per body, how many vertices coupleBodies would couple to it (glues and closing contacts).
void countCouplings(const PaperSheet& s, const std::vector<PointContact>& contacts, const RigidTable& rigids,
                    const PaperStep& ctx, std::vector<double>& count);
/// After the solve: each coupled body is moved by what its share gained times h (the world
/// turns the move into velocity); a contact only pushes, never pulls.
void releaseBodies(const PaperSheet& s, const std::vector<BodyCoupling>& couplings, RigidTable& rigids, const PaperStep& ctx);
/// Resolves the vertices' contacts with rigid bodies (velocity level, with Coulomb
/// friction, equal and opposite impulses to movable bodies). `contacts` are this sheet's.
void resolveContacts(PaperSheet& s, const std::vector<PointContact>& contacts, RigidTable& rigids, const PaperStep& ctx);
/// Moves the vertices by their velocities, holds pins and glued vertices, and gives glued
/// bodies the sheet's pull.
void integratePositions(PaperSheet& s, RigidTable& rigids, const PaperStep& ctx);

// --- hinge.cpp ---
/// Draws whether a spring compressed to `ratio` = l/l0 (having survived `survived`
/// compression before) breaks now: Paper Eq. 7, conditioned on having survived.
bool drawBreak(double ratio, double survived, double phi, std::mt19937_64& rng);
/// Lift of the inserted vertex, Paper Eq. 8: h = psi/2 sqrt(l0^2 - l^2), m.
double creaseLift(double rest, double length, double psi);
/// Breaks the compressed breakable springs (inserting a lifted vertex each, with the
/// re-triangulation and the auxiliary spring) and inserts hinge springs across folded
/// edges. Appends Crease and Hinge events.
void creaseAndFold(PaperSheet& s, PaperId id, const PaperStep& ctx, std::vector<Event>& events);
/// Breaks structural spring `index` now (a vertex inserted, lifted by Eq. 8). Returns the
/// new vertex, or UINT32_MAX when the spring cannot break (not an edge of a triangle).
std::uint32_t breakSpring(PaperSheet& s, std::uint32_t index);

// --- tension.cpp ---
/// Per-spring tensions of the step (s.tension), before the positions are updated:
/// the springs' forces (Stretch) or Yarn's momentum balance (Momentum).
/// Vertices with a contact are left out of the balance (the contact's force is unknown).
void estimateTension(PaperSheet& s, const std::vector<PointContact>& contacts, const PaperStep& ctx);

// --- tear.cpp ---
/// Separates the mesh where a structural edge is stretched past rupture_stretch
/// (vertices duplicated along the cut). Appends Tear events.
void tear(PaperSheet& s, PaperId id, const PaperStep& ctx, std::vector<Event>& events);
/// Splits vertex `vertex` of the sheet along the fan edge (vertex, across), and along
/// (vertex, across2) too when that is given (an inner vertex: a slit through it needs two
/// cuts): the triangles on one side get a new vertex. Returns the new vertex or
/// UINT32_MAX when the split is not possible (the cuts separate nothing, or a cut is not
/// an inner fan edge).
std::uint32_t splitVertex(PaperSheet& s, std::uint32_t vertex, std::uint32_t across, std::uint32_t across2 = UINT32_MAX);

// --- mesh.cpp ---
/// Appends a vertex (all per-vertex arrays grow); returns its index.
std::uint32_t addVertex(PaperSheet& s, Vec3 x, Vec3 v, double mass);
/// Appends a spring; returns its index.
std::uint32_t addSpring(PaperSheet& s, std::uint32_t a, std::uint32_t b, double rest, double k, PaperSpringKind kind);
/// Rebuilds the adjacency lists from the triangles and springs.
void buildAdjacency(PaperSheet& s);
/// Appends a triangle; returns its index.
std::uint32_t addTriangle(PaperSheet& s, const std::array<std::uint32_t, 3>& t);
/// Sets corner c of triangle t to vertex v.
void setCorner(PaperSheet& s, std::uint32_t t, int c, std::uint32_t v);
/// Sets a name of spring k: slot 0 = a, 1 = b, 2 = hinge[0], 3 = hinge[1] (UINT32_MAX = none).
void setSpringName(PaperSheet& s, std::uint32_t k, int slot, std::uint32_t v);
/// Triangles that use vertex v (indices into s.triangles).
void trianglesOf(const PaperSheet& s, std::uint32_t v, std::vector<std::uint32_t>& out);
/// Triangles that have the edge {a, b}.
void trianglesWithEdge(const PaperSheet& s, std::uint32_t a, std::uint32_t b, std::vector<std::uint32_t>& out);
/// The vertex of triangle t that is neither a nor b.
std::uint32_t thirdVertex(const std::array<std::uint32_t, 3>& t, std::uint32_t a, std::uint32_t b);
/// Unit normal of triangle t (counter-clockwise), or zero when degenerate.
Vec3 triangleNormal(const PaperSheet& s, const std::array<std::uint32_t, 3>& t);
/// True when a live non-structural spring still has what it spans: a Bending or Hinge
/// spring the two triangles of its hinge edge with its ends opposite; an Auxiliary spring
/// the two edges from its ends to its crease vertex (hinge[0]).
bool springHolds(const PaperSheet& s, const PaperSpring& sp);
/// After a change of topology around `vertex` (split into `vertex` and `twin`, or
/// re-triangulated when twin is UINT32_MAX): every live non-structural spring that names
/// them is renamed to the side where it still holds, or retired (broken) when it holds on
/// neither, so that no spring dangles across a cut or a crease.
void revalidateSprings(PaperSheet& s, std::uint32_t vertex, std::uint32_t twin);
/// Checks the mesh: every triangle non-degenerate (area > min_area), consistently oriented
/// (shared edges traversed in opposite directions), edges shared by at most two triangles,
/// every live structural spring an edge of a triangle and every edge a live structural
/// spring, every spring's vertices in range and distinct, masses positive and summing to
/// the sheet's. Returns "" when valid, else what is wrong.
std::string checkMesh(const PaperSheet& s, double min_area = 1e-14);
/// The same check on a view (what World::viewPaper gives), against the sheet's mass.
std::string checkMesh(const PaperView& v, double total_mass, double min_area = 1e-14);

}  // namespace tearables::detail
