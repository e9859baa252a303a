// The per-instance state of a cloth (structure of arrays, indices not pointers) and the
// system that steps the cloths of a world.
#pragma once

#include "linalg/dissection.hpp"
#include "linalg/supernodal.hpp"
#include "sim/hold.hpp"
#include "sim/host_contacts.hpp"
#include "sim/material_curve.hpp"
#include "sim/rigid_table.hpp"
#include "sim/step_context.hpp"
#include "tearables/cloth.hpp"
#include "tearables/world.hpp"

#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>

#include <array>
#include <functional>
#include <memory>
#include <random>
#include <vector>

namespace tearables::detail {

using SparseMatrix = Eigen::SparseMatrix<double>;
/// The fallback of both cloth solves when the supernodal LL^T finds a pivot that is not
/// positive (linalg/supernodal.hpp): a sparse LDL^T. The unknowns are numbered in a
/// nested-dissection order of the weave (gridDissection) before assembly, so both
/// factorisations keep that order (no ordering of their own).
using ClothLDLT = Eigen::SimplicialLDLT<SparseMatrix, Eigen::Lower, Eigen::NaturalOrdering<int>>;

/// A soft internal spring (shear diagonal or bending across two edges): an internal force
/// F_in of the tension solve, never strain limited.
struct SoftSpring {
    std::uint32_t a = 0, b = 0;
    double rest = 0.0;       ///< m
    double stiffness = 0.0;  ///< N/m
    bool alive = true;       ///< false once a yarn it depends on tore
};

/// A contact of one vertex with a rigid body this step.
struct VertexContact {
    std::uint32_t vertex = 0;
    Vec3 normal = Vec3::UnitY();  ///< from the body toward the vertex
    Vec3 point = Vec3::Zero();    ///< on the body's surface at its current pose, m
    Vec3 local = Vec3::Zero();    ///< the same point in the body's frame (follows the body), m
    RigidId body;
    int node = -1;                ///< index into body_nodes when the body is movable
    double friction = 0.5;
    double force = 0.0;           ///< normal force of the converged solve, N
};

/// A linear penalty row of the strain-limit solve: g = n . x_vertex - n . (u + w x arm) - offset,
/// one-sided (a contact: g >= 0) or two-sided (one axis of a glue to a movable body).
struct PenaltyRow {
    std::uint32_t vertex = 0;
    Vec3 normal = Vec3::UnitY();
    double offset = 0.0;       ///< m
    int node = -1;             ///< body node, or -1 (immovable body)
    Vec3 arm = Vec3::Zero();   ///< from the body's centre to the point, m
    bool one_sided = true;
    int contact = -1;          ///< index into contacts (one-sided rows)
};

/// A movable rigid body touched or held by a cloth: 6 unknowns (translation, rotation
/// vector) in the cloth's Newton solve.
struct ClothBodyNode {
    RigidId body;
    Eigen::Matrix<double, 6, 1> u = Eigen::Matrix<double, 6, 1>::Zero();  ///< displacement this step
    Eigen::Matrix<double, 6, 6> mass = Eigen::Matrix<double, 6, 6>::Identity();  ///< generalised mass, world frame
    int dof = 0;                  ///< first unknown of this node
};

struct ClothState {
    ClothDesc desc;
    bool alive = true;
    /// The slot's generation (the id's): grows by one when the object is removed.
    std::uint32_t generation = 0;
    bool frozen = false;
    int nu = 0, nv = 0;  ///< vertices along local x and z

    // --- vertices ------------------------------------------------------------------------
    std::vector<Vec3> x, v, x_prev, x_pred, force;
    std::vector<double> mass;
    std::vector<ParticleHold> hold;   ///< Free, Pin (world point) or Glue (body, local point)

    // --- yarn edges -----------------------------------------------------------------------
    std::vector<std::array<std::uint32_t, 2>> edges;
    std::vector<YarnKind> kinds;
    std::vector<double> rest_length, original_length, max_length, tension, stiffness, peak_stress;
    std::vector<std::uint8_t> broken, yielded;
    std::vector<SegmentMaterial> material;
    std::vector<std::vector<std::uint32_t>> edge_springs;  ///< per edge: soft springs that go when it tears
    std::vector<std::vector<std::uint32_t>> vertex_edges;  ///< per vertex: incident yarn edges
    std::vector<SoftSpring> springs;
    double shortest_rest = 0.0;

    // --- this step's contacts and bodies ---------------------------------------------------
    std::vector<VertexContact> contacts;
    std::vector<ClothBodyNode> nodes;
    std::vector<PenaltyRow> penalty;
    double penalty_stiffness = 0.0;   ///< N/m

    // --- strain limit solver scratch ------------------------------------------------------
    std::vector<int> dof;             ///< per vertex: first unknown, or -1 when fixed
    int unknowns = 0;
    std::vector<Eigen::Triplet<double>> triplets;
    std::vector<std::array<int, 2>> hessian_block_at;    ///< this assembly's 3x3 blocks: first row, first column
    std::vector<Mat3> hessian_block;                     ///< and their values
    std::vector<std::array<int, 2>> hessian_pattern_at;  ///< the blocks the pattern of `hessian` was built from
    std::vector<std::array<int, 3>> hessian_slot;        ///< per block: where its three columns start in hessian's values
    std::vector<std::uint8_t> hessian_first;             ///< per block: the first one summed into its tile
    SparseMatrix hessian;                      ///< both triangles
    Eigen::VectorXd gradient, step, trial_u;
    /// The preconditioner of the Newton system (strain_limit.cpp): the Hessian with the
    /// blocks that link vertices of different cells (the bending springs') lumped onto their
    /// diagonals; lower triangle. Its values come from the Hessian's: preconditioner values
    /// [copy_to[k]] = hessian values [copy_from[k]], then [lump_to[k]] -= [lump_from[k]].
    SparseMatrix preconditioner;
    std::vector<int> precondition_copy_to, precondition_copy_from, precondition_lump_to, precondition_lump_from;
    SupernodalLLT newton_llt;                  ///< the preconditioner's factors (the pattern's analysis is kept)
    bool newton_factored_llt = false;          ///< this iteration's factors are newton_llt's (else newton_solver's)
    std::unique_ptr<ClothLDLT> newton_solver;  ///< fallback: the Hessian's LDL^T (not movable itself)
    bool newton_analysed = false;
    Eigen::VectorXd cg_r, cg_z, cg_p, cg_q;    ///< the Newton system's conjugate gradients: residual, preconditioned, direction, H p
    std::vector<Vec3> x_trial;
    std::vector<double> yarn_estimate;        ///< per edge: the stretch the Newton Hessian's geometric term takes (strain_limit.cpp)
    int strain_newton_iterations = 0;         ///< the last strain solve's Newton iterations taken
    int strain_factorizations = 0;            ///< and the preconditioner's factorisations it made
    int strain_cg_iterations = 0;             ///< and its conjugate-gradient iterations, all Newton iterations
    double strain_last_move = 0.0;            ///< and its last iteration's largest move, m
    std::vector<std::uint32_t> vertex_order;  ///< fill-reducing order of the vertices (the Newton unknowns'), built once
    bool lump_bending = false;                ///< the preconditioner lumps the bending blocks (chosen with vertex_order)

    // --- tension solve (Yarn Sec. 3.2) ----------------------------------------------------
    std::vector<Mat3> projector;      ///< per vertex: I, minus the normals of the bodies pressing it
    std::vector<std::uint8_t> has_row;///< per vertex: gives momentum equations
    std::vector<Vec3> row_rhs;        ///< per vertex: b_i, N
    std::vector<Vec3> dir;            ///< per edge: unit direction
    std::vector<int> unknown;         ///< per edge: column of T, or -1 (broken)
    std::vector<std::uint32_t> columns; ///< column -> edge
    std::vector<std::uint32_t> edge_order;  ///< nested-dissection order of the edges (the columns'), built once
    SparseMatrix normal_matrix;       ///< A^T A + lambda' I (pattern fixed per topology)
    std::vector<std::vector<int>> vertex_value_index;  ///< per vertex, per pair of incident edges: index into normal_matrix's values
    SupernodalLLT tension_llt;                 ///< factors of normal_matrix (the pattern's analysis is kept)
    std::unique_ptr<ClothLDLT> tension_solver; ///< fallback
    Eigen::VectorXd rhs, solution, refine;
    Eigen::VectorXd cg_residual, cg_direction, cg_image;  ///< conjugate gradients: r, p and (A^T A) p (tension.cpp)
    std::vector<Vec3> tension_projected;  ///< assembly scratch: s_ie P e_e of the yarns at one vertex
    std::uint64_t topology = 1;       ///< bumped when a yarn tears (the solvers' patterns change)
    std::uint64_t tension_topology = 0;
    double tension_residual = 0.0;
    int tension_iterations = 0;

    std::mt19937_64 rng;

    std::size_t vertices() const { return x.size(); }
    std::size_t edgeCount() const { return edges.size(); }
};

// Stage kernels (one file each), testable without a world.
/// Builds a cloth's state from a valid descriptor.
ClothState makeCloth(const ClothDesc& desc);
/// Stage: unconstrained prediction x' = x + h v + h^2 / m (f_ext) (gravity, user forces).
void predictCloth(ClothState& c, const RigidTable& rigids, const StepContext& ctx);
/// Stage: strain limit (Newton on inertia + stiff yarn springs + soft springs + contacts).
void limitClothStrain(ClothState& c, RigidTable& rigids, const StepContext& ctx);
/// Stage: Yarn Sec. 3.2 tensions by Tikhonov-regularised least squares.
void solveClothTension(ClothState& c, const StepContext& ctx);
/// Stage: Coulomb friction of the contacts, on the velocities (after the tension solve: not tension).
void applyClothFriction(ClothState& c, RigidTable& rigids, const StepContext& ctx);
/// Stage: material response (Yarn Sec. 3.3-3.4): L_max, plasticity, rupture.
void respondClothMaterial(ClothState& c, const StepContext& ctx, std::vector<Event>& events);
/// Soft spring forces at the current positions, accumulated into `out` (per vertex, N).
void softSpringForces(const ClothState& c, std::vector<Vec3>& out);

/// True when vertices a and b are not corners of one cell of the weave (a bending spring's):
/// the strain solve's preconditioner lumps their coupling onto its diagonal.
bool clothLumped(const ClothState& c, std::uint32_t a, std::uint32_t b);
/// The fill-reducing orders of a cloth's vertices (of the strain solve's preconditioner,
/// which lumps the bending blocks, lump_bending, where that pays) and edges (built once per
/// weave; edges of a cloth that is not a full nu x nv grid get the natural order).
const std::vector<std::uint32_t>& clothVertexOrder(ClothState& c);
const std::vector<std::uint32_t>& clothEdgeOrder(ClothState& c);

/// The least-squares tension kernel on its own: rows of the free vertices (has_row,
/// projector, row_rhs), edge directions `dir`; solves min |A T - b|^2 + lambda |T - T_0|^2
/// by iterated Tikhonov from the prior and warm start T_0 in c.tension (tension.cpp).
/// Exposed for tests and benchmarks.
void solveTensionLeastSquares(ClothState& c);

/// Glues vertex `p` to `body` (in state `b`) at `local` in the body's frame and moves it
/// there: a glue from the descriptor at creation and World::attachClothToRigid alike.
inline void glueVertex(ClothState& c, std::size_t p, RigidId body, const RigidState& b, const Vec3& local) {
    c.hold[p].kind = ParticleHold::Kind::Glue;
    c.hold[p].point = local;
    c.hold[p].body = body;
    c.x[p] = gluePoint(b, local);
}

/// The cloths of a world: created, stepped and viewed through World.
class ClothSystem {
public:
    /// Validates `desc` and its attachments' bodies against `rigids`, creates the cloth and
    /// glues the vertices its attachments glue. Throws InvalidInput naming the field; nothing
    /// is created then.
    ClothId add(const ClothDesc& desc, const RigidTable& rigids);
    void remove(ClothId id);
    ClothState& get(ClothId id);
    const ClothState& get(ClothId id) const;
    bool contains(ClothId id) const;
    /// The id of the cloth in `slot` (its current generation).
    ClothId idAt(std::size_t slot) const;
    std::vector<ClothId> ids() const;
    bool empty() const;

    /// One step of every live cloth (after the strings in World::step).
    void step(RigidTable& rigids, const StepContext& ctx, const HostContacts& host, std::vector<Event>& events);
    /// Wall time of the cloths' stages in the last step, s (zero without a live cloth).
    const StageTimes& lastTimes() const { return times_; }
    /// Swept bounds of every live cloth for a step of `h` (World::meshBounds).
    void bounds(double h, const Vec3& gravity, std::vector<std::pair<Vec3, Vec3>>& out) const;
    /// True when a cloth vertex is glued to `body`.
    bool usesBody(RigidId body) const;
    /// Drops every glue to `body` (Release events with cause BodyRemoved into `pending`).
    void releaseBody(RigidId body, double time, std::int64_t step, std::vector<Event>& pending);
    /// Releases a vertex (Release event into `pending`); no-op when free.
    void release(ClothId id, std::size_t vertex, EventCause cause, double time, std::int64_t step,
                 std::vector<Event>& pending);

private:
    friend struct WorldAccess;  // snapshots read and replace the cloths (src/world/snapshot.cpp)
    void predict(const RigidTable& rigids, const StepContext& ctx);
    void collideBodies(const RigidTable& rigids, const HostContacts& host);
    void limitStrain(RigidTable& rigids, const StepContext& ctx);
    void solveTension(const StepContext& ctx);
    void respondMaterial(const StepContext& ctx, std::vector<Event>& events);
    void updateVelocities(RigidTable& rigids, const StepContext& ctx, std::vector<Event>& events);
    std::vector<ClothState> cloths_;
    PointQuery query_;
    std::vector<PointContact> found_;
    std::vector<std::uint32_t> query_cloth_;
    StageTimes times_;
};

}  // namespace tearables::detail
