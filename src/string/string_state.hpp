// The per-instance state of a string, structure of arrays, indices not pointers.
#pragma once

#include "linalg/cholesky3.hpp"
#include "sim/hold.hpp"
#include "sim/material_curve.hpp"
#include "sim/rigid_table.hpp"
#include "sim/step_context.hpp"
#include "string/contacts.hpp"
#include "string/shape_matching.hpp"
#include "tearables/string.hpp"
#include "tearables/world.hpp"

#include <Eigen/Cholesky>

#include <cmath>
#include <cstdint>
#include <memory>
#include <random>
#include <vector>

namespace tearables::detail {

struct StringState;
class ThreadPool;

/// Solves the strain limit of several strings at once, coupled by their string-string
/// contacts (cluster_solve.cpp): one Newton method on the sum of the strings' energies
/// and the contact penalties. `contacts` index into `strings`.
/// `work` is its scratch, kept by the caller so that a running step does not allocate.
struct ClusterScratch {
    ClusterScratch();
    ~ClusterScratch();
    ClusterScratch(ClusterScratch&&) noexcept;
    ClusterScratch& operator=(ClusterScratch&&) noexcept;
    struct Impl;
    std::unique_ptr<Impl> impl;
    /// Every joint step by the sparse factorisation of the whole cluster, which otherwise
    /// only the large clusters take (tests compare it with the Woodbury step).
    bool always_sparse = false;
};
void solveStringCluster(const std::vector<StringState*>& strings, std::vector<StringPairContact>& contacts,
                        RigidTable& rigids, const StepContext& ctx, ClusterScratch& work);

/// A movable body touched by a string's contacts: 6 unknowns (translation, rotation) in
/// the string's Newton solve.
struct BodyNode {
    RigidId body;
    Eigen::Matrix<double, 6, 1> impulse = Eigen::Matrix<double, 6, 1>::Zero();  ///< this string's, x h (kg m, kg m^2)
    /// This string's displacement of the body this step (translation, rotation vector),
    /// its generalised mass where the step started, and the displacement at which the
    /// contact planes were last linearised (strain_limit.cpp).
    Eigen::Matrix<double, 6, 1> displacement = Eigen::Matrix<double, 6, 1>::Zero();
    Eigen::Matrix<double, 6, 6> mass = Eigen::Matrix<double, 6, 6>::Identity();
    Eigen::Matrix<double, 6, 1> linearised_at = Eigen::Matrix<double, 6, 1>::Zero();
    BodyNode() = default;
    explicit BodyNode(RigidId b) : body(b) {}
};

/// What a step recomputes before it reads it, kept between steps only so that a running
/// step does not allocate. A snapshot keeps the part a step may read before writing
/// (src/world/snapshot.cpp) and rebuilds the rest.
struct StringScratch {
    // --- the tension and twist solves: one tridiagonal system per string (segments) --------
    std::vector<Vec3> dir;            ///< unit segment directions
    std::vector<double> diag, off, rhs;
    std::vector<double> segment_work; ///< solveSymmetricTridiagonal's gains; the strain solve's active stretches
    std::vector<std::uint8_t> active;
    /// Per particle: the first contact with a body at it (at an end of a segment), -1 if
    /// none (StringSystem::collideBodies merges repeats).
    std::vector<std::int32_t> end_contact;
    /// Per contact with a body: the entry of contact_memory its friction took, -1 if none;
    /// per entry: how many contacts took it (StringSystem::collideBodies).
    std::vector<std::int32_t> memory_taken;
    std::vector<std::uint32_t> memory_takers;

    // --- the strain solve: block-tridiagonal Newton system (particles) ----------------------
    std::vector<Mat3> blk_diag, blk_off;
    std::vector<Vec3> blk_rhs;
    std::vector<Mat3> blk_factor_gain;    ///< factorisation: U_{i-1}^T D'_{i-1}^-1 (per particle)
    std::vector<Cholesky3> blk_factor;    ///< factorisation: Cholesky of D'_i
    /// The contact-free chain's factorisation: its pivots' inverses, 6 n + 12 doubles
    /// (solveChain, linalg/block_tridiagonal.hpp), kept for a chord iteration.
    std::vector<double> chain_inverse;
    /// solveChain's pairs (t, n - 1 - t): bit 0 where t couples to t + 1, bit 1 where
    /// n - 1 - t couples to n - 2 - t, for the back substitution (n entries).
    std::vector<std::uint8_t> chain_coupled;
    std::vector<std::uint8_t> blk_coupled;  ///< factorisation: particle i is coupled to i-1 (gain != 0)
    /// The strain solve started warm this step (strain_limit.cpp, warmStart) and has not
    /// made its first Newton iteration yet.
    bool strain_warm_start = false;
    /// Slack exactly at the rest length (no taut band): set by the island solve after its
    /// first iterations (StringIslandMember::condense).
    bool exact_slack = false;
    /// Per segment (empty: none), set by the island solve: a slack segment that this
    /// iteration's step stretches (predictSprings) joins the Newton model with its slack
    /// carried, as a contact the step runs into does.
    std::vector<std::uint8_t> predicted_taut;
    /// Per particle (empty: none), set while the string's contacts with other strings are
    /// solved in an island (ClusterIslandMember): a glued particle's move in its body's
    /// step (zero for the others).
    std::vector<Vec3> held_step;
    std::vector<double> geometric_tension;  ///< per segment: the tension estimate of the chain Hessian's geometric term, N
    /// This step's strain solve of the string converged (false where its own solve stopped
    /// at the iteration cap): the return mapping of yield_in_solve trusts only a converged
    /// solve's forces (fracture.cpp).
    bool strain_converged = true;
    /// This step's strain solve takes the string's plastic branch (plastic_spring.hpp): a
    /// string with yield_in_solve that StrainSolve solves (strain_limit.cpp). Strings solved
    /// in islands or clusters, whose solves have no line search, keep the elastic spring and
    /// flow after the step from the tension estimate, as without the option.
    bool plastic_in_solve = false;
    std::vector<Mat3> row_projector;      ///< per particle: I, or I minus the normals of the bodies pressing it
    bool rows_pressed = false;            ///< whether any row_projector may differ from I (none does where false)

    // --- the strain solve's body unknowns ---------------------------------------------------
    std::vector<Eigen::Matrix<double, 6, 1>> node_step;  ///< per body node: this iteration's Newton step
    std::vector<std::vector<Vec3>> node_columns;  ///< A^-1 C, 6 columns per body node (n each; grown, never shrunk)
    std::vector<Vec3*> column_pointers;           ///< the columns one solveFactoredColumns call solves
    std::vector<std::size_t> column_firsts;       ///< and the row above which each is zero
    /// The body unknowns' Schur complement (limitStrain): per node its 6x6 block,
    /// right-hand side and coupling rows (particle, 3x6 block); the dense Schur system and
    /// its factorisation.
    struct NodeScratch {
        std::vector<Eigen::Matrix<double, 6, 6>> diag;
        std::vector<Eigen::Matrix<double, 6, 1>> rhs;
        std::vector<std::vector<std::pair<std::size_t, Eigen::Matrix<double, 3, 6>>>> coupling;
        Eigen::MatrixXd schur;
        Eigen::VectorXd rs, du;
        Eigen::LDLT<Eigen::MatrixXd> ldlt;
        NodeScratch() = default;
        // A copy starts empty: it is scratch, and an Eigen::LDLT that has not factorised
        // yet holds an uninitialised status that copying it would read (UBSan).
        NodeScratch(const NodeScratch&) {}
        NodeScratch& operator=(const NodeScratch&) { return *this; }
    } node_scratch;

    // --- chain shape matching (Strings Sec. 3) ----------------------------------------------
    /// Per particle: its goal displacement for this step's prediction (free), or the
    /// reaction its body takes, kg m (glued); zero where pinned.
    std::vector<Vec3> csm_goal;
    CsmScratch csm_scratch;

    // --- twist (Strings Sec. 4) -------------------------------------------------------------
    /// This step's twist solve was skipped: the string is untwisted (solveTwist), so every
    /// twist moment is zero; and twist_force is all zero (computeTwistForces).
    bool twist_skipped = false;
    bool twist_force_zero = false;
    /// This step's factor on every twist force (predict.cpp, twistScale): 1 unless the cap
    /// acts.
    double twist_scale = 1.0;
};

/// Counters of the last step, for tests and benchmarks; nothing reads them in the step.
struct StringDiagnostics {
    int strain_newton_iterations = 0;     ///< iterations of this step's strain solves, chord ones included
    int strain_chord_iterations = 0;      ///< of which chord iterations
};

struct StringState {
    StringDesc desc;
    bool alive = true;
    /// The slot's generation (the id's): grows by one when the object is removed.
    std::uint32_t generation = 0;
    bool frozen = false;

    // --- particles (n + 1) --------------------------------------------------------------
    std::vector<Vec3> x;          ///< position, m
    std::vector<Vec3> v;          ///< velocity, m/s
    std::vector<Vec3> x_prev;     ///< position at the start of the step
    std::vector<Vec3> x_pred;     ///< position before strain limiting (for the tension solve)
    std::vector<Vec3> v_prev;     ///< BDF2 strings: velocity at the start of the previous step (v_{n-1})
    std::vector<Vec3> x_older;    ///< BDF2 strings: position at the start of the previous step (x_{n-1}; set by predict)
    /// This step's weight of a free particle's inertia over m / h^2: 9/4 for a BDF2 step,
    /// 1 for backward Euler (predict sets it; the solves and the tension read it, and the
    /// next step's predict, whose BDF2 history is valid only after a BDF2 step).
    double inertia_gain = 1.0;
    std::vector<Vec3> force;      ///< user force for this step, N
    std::vector<double> mass;     ///< kg
    std::vector<double> inv_mass; ///< 1/kg of the free particle (holds are separate)
    std::vector<ParticleHold> hold;
    std::vector<Vec3> glue_impulse;  ///< Glue: impulse x h the segments gave the body this step, kg m
    std::vector<std::uint8_t> glue_movable;  ///< Glue: the body could move this step (dynamic and awake)
    /// The string is solved in an island (src/island/) this stage: its particles glued to
    /// movable bodies are fixed rows that follow their bodies' unknowns.
    bool island_glue = false;

    // --- segments (n) ---------------------------------------------------------------------
    std::vector<double> rest_length;  ///< L0, m (grows with plasticity)
    std::vector<double> max_length;   ///< strain limit L_max = L_rest (1 + sigma/E), m (reported)
    std::vector<double> compliance;   ///< L_rest / (E A), m/N: elastic stretch per newton
    std::vector<double> tension;      ///< N
    std::vector<double> twist;        ///< rad
    std::vector<double> radius;       ///< m (volume preserving under stretch)
    std::vector<std::uint8_t> broken; ///< 1 = torn
    std::vector<std::uint8_t> yielded;///< 1 = passed the tensile yield point once
    std::vector<double> original_length;  ///< L0 at creation, m
    std::vector<double> peak_stress;      ///< highest tensile stress past yield so far, Pa (hardening)
    std::vector<SegmentMaterial> material;
    std::vector<double> spring_force;     ///< per segment: k c of the last Newton iteration, N
    std::vector<double> prev_stretch;     ///< segment stretch at the start of the step, m

    // --- rigid contacts (collision stage) -------------------------------------------------
    std::vector<RigidSegmentContact> contacts;
    /// The contacts with friction at the end of the last step, sorted (finishChain; read
    /// and cleared by StringSystem::collideBodies).
    std::vector<ContactMemory> contact_memory;
    std::vector<BodyNode> body_nodes;
    std::vector<std::uint8_t> colliding;  ///< per particle: in a string-string contact last step (3x heavier in CSM)
    /// Per segment: may still be inside a body it overlapped when the string was made
    /// (created through a block, or held inside one): cleared at the first step it is not,
    /// never set again. Such overlaps are pushed out gradually, or not at all next to a
    /// hold (StringSystem::collideBodies); any other overlap is the contacts' own give and
    /// is pushed back at once (a fast body must not pass).
    std::vector<std::uint8_t> made_inside;
    /// The bodies an Overlap event has named for this string: a start overlap is reported
    /// once per body, at the first step it is pushed out.
    std::vector<RigidId> overlap_reported;

    // --- chain shape matching (Strings Sec. 3) -----------------------------------------
    std::vector<Vec3> rest_direction;     ///< per segment, unit direction at creation
    std::vector<Vec3> rest_shape;         ///< per particle, rest positions from the rest lengths
    std::vector<double> csm_mass;         ///< per particle (colliding particles weigh 3x, Sec. 6)

    // --- twist (Strings Sec. 4) --------------------------------------------------------
    std::vector<double> twist_velocity;   ///< per segment, rad/s
    std::vector<double> twist_old;        ///< per segment, angle at the start of the stage
    std::vector<double> twist_inertia;    ///< per segment, m r^2 / 2, kg m^2
    std::vector<double> twist_width;      ///< per segment w_twist (rigidity factor w/2)
    std::vector<double> rest_twist;       ///< per joint (segments k, k+1), rad (torsion plasticity)
    std::vector<double> joint_stiffness;  ///< per joint, G J w / (2 l), N m / rad (refreshed by twist solves; see solveTwist)
    std::vector<double> torsion_peak;     ///< per joint, peak torsional strain past yield
    std::vector<double> joint_strain;     ///< per joint, |gamma| this step
    std::vector<std::uint8_t> torsion_yielded;  ///< per joint
    std::vector<Vec3> twist_force;        ///< per particle, N (Eq. 6), applied next step
    double end_twist[2] = {0.0, 0.0};     ///< held angle of clamped ends (first, last segment), rad
    /// Per segment: the director of its twist-free (Bishop) frame where the last twist solve
    /// left it, unit and normal to the segment (twist.cpp, followFrames); empty while the
    /// string is untwisted (the twist solve skipped).
    std::vector<Vec3> twist_frame;
    double twist_glued_pred[2] = {0.0, 0.0};
    double twist_glued_axis_inertia[2] = {0.0, 0.0};
    double shortest_rest = 0.0;           ///< m, for the convergence tolerance

    std::mt19937_64 rng;

    StringScratch scratch;        ///< the solvers' work arrays (no allocation in the step)
    StringDiagnostics diagnostics;

    std::size_t particles() const { return x.size(); }
    std::size_t segments() const { return rest_length.size(); }
};

// Stage kernels, one file each.
void predict(StringState& s, const RigidTable& rigids, const StepContext& ctx);
void predictBackwardEuler(StringState& s, const StepContext& ctx);
void prepareStrainLimit(StringState& s, RigidTable& rigids, const StepContext& ctx);
/// Returns the largest move (m) of its first Newton iteration: how far the string was
/// from its solution when called (StringSystem::limitStrain stops the sweeps over strings
/// that share bodies when every string is already there).
double limitStrain(StringState& s, RigidTable& rigids, const StepContext& ctx);
void estimateTension(StringState& s, const StepContext& ctx);
void respondMaterial(StringState& s, StringId id, const StepContext& ctx, std::vector<Event>& events);
void updateVelocities(StringState& s, const StepContext& ctx);
void clampTravel(StringState& s, const StepContext& ctx);
/// The previous step's twist force on particle p as the prediction applies it (scaled by
/// the cap, scratch.twist_scale).
inline Vec3 cappedTwistForce(const StringState& s, std::size_t p) { return s.scratch.twist_scale * s.twist_force[p]; }
void updateTwistStiffness(StringState& s);
void updateRestShape(StringState& s);
void shapeMatch(StringState& s, ThreadPool* pool = nullptr);
void solveTwist(StringState& s, RigidTable& rigids, const StepContext& ctx);
void computeTwistForces(StringState& s);

}  // namespace tearables::detail
