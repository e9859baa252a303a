// A contact provider for core tests without Bullet: string segments against one sphere,
// speculative from the start positions (as the Bullet plugin reports them: contacts within
// the distance the segment can travel this step, plus 5 mm).
#pragma once

#include "tearables/world.hpp"

#include <algorithm>
#include <vector>

namespace tearables::testing {

class SphereContacts : public ContactProvider {
public:
    /// A sphere at a fixed centre (a static body).
    SphereContacts(RigidId body, const Vec3& centre, double radius, double friction)
        : body_(body), centre_(centre), radius_(radius), friction_(friction) {}
    /// The sphere of radius `radius` around body `body` of `world`: it follows the body.
    SphereContacts(RigidId body, const World& world, double radius, double friction)
        : body_(body), radius_(radius), friction_(friction), world_(&world) {}

    /// Writes into `out` only (whose storage the world keeps): allocates nothing itself.
    void findContacts(const CollisionQuery& q, std::vector<RigidContact>& out) override {
        const Vec3 centre = world_ ? world_->rigid(body_).position : centre_;
        for (std::size_t i = 0; i < q.strings.size(); ++i) {
            const auto& start = *q.start[i];
            const auto& pred = *q.predicted[i];
            for (std::size_t j = 0; j + 1 < start.size(); ++j) {
                if ((*q.broken[i])[j]) continue;
                const Vec3 a = start[j], ab = start[j + 1] - start[j];
                const double s = std::clamp((centre - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
                const Vec3 d = a + s * ab - centre;
                const double travel = std::max((pred[j] - start[j]).norm(), (pred[j + 1] - start[j + 1]).norm());
                if (d.norm() > radius_ + (*q.radius[i])[j] + travel + 0.005 || d.norm() < 1e-9) continue;
                RigidContact c;
                c.string = q.strings[i];
                c.segment = static_cast<std::uint32_t>(j);
                c.s = s;
                c.normal = d.normalized();
                c.point = centre + radius_ * c.normal;
                c.body = body_;
                c.friction = friction_;
                out.push_back(c);
            }
        }
    }

private:
    RigidId body_;
    Vec3 centre_ = Vec3::Zero();
    double radius_;
    double friction_;
    const World* world_ = nullptr;
};

}  // namespace tearables::testing
