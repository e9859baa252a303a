// Cloth of tearable yarns (issue 6): descriptor checks, strain limiting, least-squares
// tensions against analytic results, material response and tearing.
#include "cloth/cloth_state.hpp"
#include "tearables/world.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <set>

namespace {

using tearables::ClothDesc;
using tearables::ClothId;
using tearables::ClothView;
using tearables::EventType;
using tearables::InvalidInput;
using tearables::Vec3;
using tearables::World;
using tearables::YarnKind;

constexpr double kPi = 3.14159265358979323846;

/// A vertical yarn of `n` vertices hanging from (0, 1, 0): a cloth of resolution 1 x n in
/// a frame turned so that its local z axis points down.
ClothDesc yarn(int n, double length) {
    ClothDesc d;
    d.resolution = {1, n};
    d.size = {0.0, length};
    d.origin = Vec3(0, 1, 0);
    d.orientation = tearables::Quat(Eigen::AngleAxisd(kPi / 2, Vec3::UnitX()));  // local z -> world -y
    d.areal_density = 0.0;
    d.density = 1150.0;
    d.yarn_radius = 5e-4;
    d.material.variation = 0.0;
    d.pins = {{0, 0}};
    return d;
}

ClothDesc square(int n, double size) {
    ClothDesc d;
    d.resolution = {n, n};
    d.size = {size, size};
    d.origin = Vec3(0, 1, 0);
    d.material.variation = 0.0;
    return d;
}

double stressOf(const ClothView& v, std::size_t e) {
    return std::max(0.0, (*v.tension)[e]) / (kPi * v.yarn_radius * v.yarn_radius);
}

}  // namespace

// Yarn Sec. 3.2 on a chain: the least-squares tensions equal the direct chain solve, the
// back substitution from the free end (T_i = -e_i . sum_{k > i} b_k, exact where the
// system is consistent), within 1e-6 relative; the chain is given a general motion
// (random strain-limited positions would not be consistent, so the rows come from a
// known set of tensions: b = A T_true).
TEST(ClothTension, ChainLeastSquaresEqualsDirectSolve) {
    for (int n : {3, 10, 40}) {
        tearables::detail::ClothState c = tearables::detail::makeCloth(yarn(n, 0.5));
        std::mt19937_64 rng(7);
        std::uniform_real_distribution<double> u(-1.0, 1.0);
        // A wiggly chain with unit edge directions.
        for (std::size_t p = 1; p < c.vertices(); ++p) c.x[p] = c.x[p - 1] + Vec3(0.3 * u(rng), -1.0, 0.3 * u(rng)).normalized() * 0.01;
        for (std::size_t e = 0; e < c.edgeCount(); ++e) c.dir[e] = (c.x[c.edges[e][1]] - c.x[c.edges[e][0]]).normalized();
        std::vector<double> truth(c.edgeCount());
        for (double& t : truth) t = 5.0 + 4.0 * u(rng);
        std::fill(c.row_rhs.begin(), c.row_rhs.end(), Vec3::Zero());
        for (std::size_t e = 0; e < c.edgeCount(); ++e) {
            c.row_rhs[c.edges[e][0]] += truth[e] * c.dir[e];
            c.row_rhs[c.edges[e][1]] -= truth[e] * c.dir[e];
        }
        for (std::size_t p = 0; p < c.vertices(); ++p) c.has_row[p] = p == 0 ? 0 : 1;  // vertex 0 pinned
        std::fill(c.tension.begin(), c.tension.end(), 0.0);  // cold start
        tearables::detail::solveTensionLeastSquares(c);
        // The direct chain solve: sum the rows from the free end.
        Vec3 below = Vec3::Zero();
        for (std::size_t e = c.edgeCount(); e-- > 0;) {
            below += c.row_rhs[c.edges[e][1]];
            const double direct = -c.dir[e].dot(below);
            EXPECT_NEAR(c.tension[e], direct, 1e-6 * std::abs(direct)) << "n " << n << " edge " << e;
            EXPECT_NEAR(direct, truth[e], 1e-9 * truth[e]);
        }
        EXPECT_LT(c.tension_residual, 1e-6);
    }
}

// A yarn hanging from its top at rest in a world: each yarn carries the weight below it.
TEST(ClothTension, HangingYarnCarriesTheWeightBelow) {
    World world;
    const ClothId id = world.addCloth(yarn(21, 0.5));
    for (int i = 0; i < 50; ++i) world.step(0.01);
    const ClothView v = world.viewCloth(id);
    const double g = 9.81;
    double below = 0.0;
    for (std::size_t e = v.edgeCount(); e-- > 0;) {
        below += (*v.masses)[(*v.edges)[e][1]] * g;
        EXPECT_NEAR((*v.tension)[e], below, 1e-3 * below) << e;
    }
}
