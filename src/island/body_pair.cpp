// Members between two bodies (body_pair.hpp).
#include "island/body_pair.hpp"

namespace tearables::detail {

PairOrder orderPair(RigidId a, RigidId b, const RigidTable& rigids) {
    if (a.valid() && !rigids.holds(a)) return PairOrder::Drop;
    if (b.valid() && !rigids.holds(b)) return PairOrder::Drop;
    if (a.valid() && b.valid() && a.index == b.index) return PairOrder::Drop;
    if (a.valid() && rigids.movable(a)) return PairOrder::Keep;
    return b.valid() && rigids.movable(b) ? PairOrder::Swap : PairOrder::Drop;
}

void BodyPairMember::startPair(RigidId a, RigidId b, const RigidTable& rigids) {
    b_moves_ = b.valid() && rigids.movable(b);
    bodies_.assign(1, a);
    if (b_moves_) bodies_.push_back(b);
    disp_a_.setZero();
    disp_b_.setZero();
    du_a_.setZero();
    du_b_.setZero();
}

void BodyPairMember::addTo(const std::vector<int>& slot, Eigen::MatrixXd& system, Eigen::VectorXd& rhs) const {
    const Eigen::Index a = 6 * slot[0];
    system.block<6, 6>(a, a) += hessian_.topLeftCorner<6, 6>();
    rhs.segment<6>(a) -= gradient_.head<6>();
    if (!b_moves_) return;
    const Eigen::Index b = 6 * slot[1];
    system.block<6, 6>(a, b) += hessian_.topRightCorner<6, 6>();
    system.block<6, 6>(b, a) += hessian_.bottomLeftCorner<6, 6>();
    system.block<6, 6>(b, b) += hessian_.bottomRightCorner<6, 6>();
    rhs.segment<6>(b) -= gradient_.tail<6>();
}

void BodyPairMember::backSubstitute(const std::vector<int>& slot, const Eigen::VectorXd& du) {
    du_a_ = du.segment<6>(6 * slot[0]);
    du_b_ = b_moves_ ? Vec6(du.segment<6>(6 * slot[1])) : Vec6::Zero();
}

void BodyPairMember::takeDisplacements(const std::vector<int>& slot, const Eigen::VectorXd& displacement) {
    disp_a_ = displacement.segment<6>(6 * slot[0]);
    if (b_moves_) disp_b_ = displacement.segment<6>(6 * slot[1]);
}

}  // namespace tearables::detail
