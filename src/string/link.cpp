// Twist and writhe of a string (tearables/queries.hpp, linkMeasure).
//
// Writhe: Klenin and Langowski, "Computation of writhe in modeling of supercoiled DNA",
// Biopolymers 54 (2000) 307, method 1a. For segments i (p1 -> p2) and j (p3 -> p4) the
// Gauss integral over the pair is Omega / 4 pi, Omega the signed solid angle subtended by
// the quadrilateral the two segments span: with r_ab = p_b - p_a and the unit normals
// n1 = r13 x r14, n2 = r14 x r24, n3 = r24 x r23, n4 = r23 x r13,
//   Omega = (asin(n1.n2) + asin(n2.n3) + asin(n3.n4) + asin(n4.n1)) sign((r34 x r12).r13),
// and Wr = sum over i != j of Omega_ij / 4 pi = sum over i < j of Omega_ij / 2 pi. Adjacent
// segments are coplanar (Omega = 0).
#include "base/constants.hpp"
#include "tearables/queries.hpp"

#include <algorithm>
#include <cmath>

namespace tearables {

namespace {

double solidAngle(const Vec3& p1, const Vec3& p2, const Vec3& p3, const Vec3& p4) {
    const Vec3 r13 = p3 - p1, r14 = p4 - p1, r23 = p3 - p2, r24 = p4 - p2;
    Vec3 n[4] = {r13.cross(r14), r14.cross(r24), r24.cross(r23), r23.cross(r13)};
    for (Vec3& v : n) {
        const double len = v.norm();
        if (!(len > 1e-300)) return 0.0;  // a degenerate quadrilateral (collinear, touching)
        v /= len;
    }
    double omega = 0.0;
    for (int k = 0; k < 4; ++k) omega += std::asin(std::clamp(n[k].dot(n[(k + 1) % 4]), -1.0, 1.0));
    const double sign = (p4 - p3).cross(p2 - p1).dot(r13);
    return sign > 0.0 ? omega : sign < 0.0 ? -omega : 0.0;
}

}  // namespace

LinkMeasure linkMeasure(const World& world, StringId id) {
    const StringView v = world.view(id);
    const std::vector<Vec3>& x = *v.positions;
    const std::vector<std::uint8_t>& broken = *v.broken;
    const std::size_t m = v.segmentCount();
    LinkMeasure out;
    for (std::size_t k = 0; k + 1 < m; ++k)
        if (!broken[k] && !broken[k + 1]) out.twist += (*v.twist)[k + 1] - (*v.twist)[k];
    out.twist /= 2.0 * detail::kPi;
    double sum = 0.0;
    for (std::size_t i = 0; i < m; ++i) {
        if (broken[i]) continue;
        for (std::size_t j = i + 2; j < m; ++j)
            if (!broken[j]) sum += solidAngle(x[i], x[i + 1], x[j], x[j + 1]);
    }
    out.writhe = sum / (2.0 * detail::kPi);
    return out;
}

double polylineWrithe(const std::vector<Vec3>& x) {
    double sum = 0.0;
    for (std::size_t i = 0; i + 1 < x.size(); ++i)
        for (std::size_t j = i + 2; j + 1 < x.size(); ++j) sum += solidAngle(x[i], x[i + 1], x[j], x[j + 1]);
    return sum / (2.0 * detail::kPi);
}

}  // namespace tearables
