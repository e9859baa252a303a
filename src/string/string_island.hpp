// A string as a member of an island (sim/island.hpp): its chain eliminated onto the
// movable bodies it is glued to and touches.
#pragma once

#include "sim/body_motion.hpp"
#include "sim/island.hpp"
#include "string/string_state.hpp"

#include <cstddef>
#include <vector>

namespace tearables::detail {

class StringIslandMember final : public IslandMember {
public:
    /// After prepareStrainLimit: the string's particles glued to movable bodies become rows
    /// that follow their bodies, each such body a node of the string. A member is reused
    /// step after step (its arrays keep their capacity).
    void start(StringState& s, RigidTable& rigids, const StepContext& ctx);

    const std::vector<RigidId>& bodies() const override { return bodies_; }
    StringState& string() const { return *string_; }
    /// Particle p's body node where it is glued to a movable body (its motion is the
    /// body's: J = glueJacobianAt(p), dx = J du), else -1.
    int gluedNode(std::size_t p) const {
        return glued_index_[p] < 0 ? -1 : static_cast<int>(glued_[static_cast<std::size_t>(glued_index_[p])].node);
    }
    Mat36 glueJacobianAt(std::size_t p) const { return glueJacobian(glued_[static_cast<std::size_t>(glued_index_[p])]); }
    bool touchesBodies() const override { return !string_->contacts.empty(); }
    void addWarmHints(const std::vector<int>& slot, std::vector<Mat6>& normal, Eigen::VectorXd& rhs) const override;
    void warmStep(const std::vector<int>& slot, const Eigen::VectorXd& du) override;
    void holdStep(const std::vector<int>& slot, const Eigen::VectorXd& du) override;
    void beginPass() override;
    void condense(bool fresh) override;
    /// condense() in two halves, for a member that adds terms of its own to the string's
    /// system between them (ClusterIslandMember): the chain's, its contacts' and its glue's
    /// blocks and gradient (blk_diag, blk_off, blk_rhs and the node scratch), then the
    /// chain's factorisation, y = A^-1 r into blk_rhs and the Schur complement.
    void assembleSystem(bool fresh);
    void factorAndCondense();
    bool condenseChord() override;
    void cancelChord() override { --iteration_; }
    void addTo(const std::vector<int>& slot, Eigen::MatrixXd& system, Eigen::VectorXd& rhs) const override;
    void addRhsTo(const std::vector<int>& slot, Eigen::VectorXd& rhs) const override;
    void addTurningSoftening(const std::vector<int>& slot, std::vector<Mat3>& softening) const override;
    void backSubstitute(const std::vector<int>& slot, const Eigen::VectorXd& du) override;
    bool addPredictedContacts() override;
    double energy(double alpha) const override;
    double apply(double alpha, const std::vector<int>& slot, const Eigen::VectorXd& displacement) override;
    bool frictional() const override;
    double reweigh() override;
    void finish(int iterations) override;

private:
    void seedFriction();
    /// A particle glued to a movable body: its node (body_nodes), its point in the body,
    /// and where its own velocity takes it (x_prev + h v): its inertia pulls its body there.
    /// (The host moved the body without the particle's mass: a point it turns carries its
    /// momentum along, and the island gives it back.)
    struct Glued {
        std::size_t particle;
        std::size_t node;
        Vec3 local;
        Vec3 inertial;
    };
    /// Where the glued particle is with its body displaced by alpha times its node's step.
    Vec3 trialGlue(const Glued& g, double alpha) const;
    /// Adds the glued particles' rows (their springs and own inertia) to the nodes' blocks:
    /// their gradient to `rhs`, and with `hessian` their blocks and couplings.
    void assembleGlue(bool hessian);
    /// Adds the glued ends' shares of the contacts on their segments (assembleGlueContacts).
    void assembleGlueContacts();
    /// One contact term with residual r (Hessian `hess`, gradient `grad` in r) whose
    /// Jacobian is `along` times x(s)'s motion and `body` times the touched body's: its
    /// blocks that involve a glued end's body.
    void addGlueShare(const RigidSegmentContact& c, const Mat3& hess, const Vec3& grad, const Mat3& along, const Mat36& body);
    /// A glued particle's motion in its body's (u, theta): [I, -[r]x].
    Mat36 glueJacobian(const Glued& g) const;
    /// Adds a node-node block (rows of a, columns of b) and its transpose to the system.
    void addCross(std::size_t a, std::size_t b, const Mat6& block);
    void addTurningStiffness();
    bool condenseRows();
    /// The condensed right-hand side r_b - C^T y for y = A^-1 r in blk_rhs, with the
    /// couplings C of the last condense().
    void condenseRhs();

    StringState* string_ = nullptr;
    RigidTable* rigids_ = nullptr;
    const StepContext* ctx_ = nullptr;
    std::vector<RigidId> bodies_;
    std::vector<Glued> glued_;
    std::vector<std::uint8_t> is_glued_;        ///< per particle
    std::vector<int> glued_index_;              ///< per particle: index into glued_, or -1
    std::vector<std::size_t> glue_segments_;    ///< the segments of glued particles, ascending
    std::size_t contact_nodes_ = 0;             ///< body_nodes from contacts (the rest from glue)
    int iteration_ = 0;                         ///< Newton iterations of this pass so far
    bool seed_friction_ = false;                ///< the step's first pass is still to begin (seedFriction)
    /// Node-node blocks (both glued ends of one segment): (a, b, block of a's rows, b's columns).
    struct Cross {
        std::size_t a, b;
        Mat6 block;
    };
    std::vector<Cross> cross_;
    mutable std::vector<Vec3> trial_;  ///< energy's trial positions
    std::vector<Mat3> softening_;      ///< per body node: the turning stiffness's negative part
    std::vector<Vec3> pull_;           ///< per glued particle: its springs' pull on it
    std::vector<Vec3> held_step_;      ///< per particle: a glued one's move in its body's step
    // condenseRows: the coupled rows, each particle's row (-1: none), the couplings
    // stacked by row (3|R| x 6 nodes), A^-1 at the rows, and whether this system used them.
    std::vector<std::size_t> rows_;
    std::vector<int> row_of_;
    Eigen::MatrixXd rows_coupling_, rows_inverse_;
    bool by_rows_ = false;
};

}  // namespace tearables::detail
