// tearables: the Bullet plugin with the whole core, for power users of BulletWorld::core():
// the core World (views, settings, events, stage times), every descriptor, the controls and
// queries on the core, and the conversions between Bullet's vectors and the core's Eigen
// ones. Everyday use needs only tearables/bullet.hpp (no Eigen); this header costs what the
// core's headers cost to compile (docs/facade.md).
#pragma once

#include "tearables/bullet.hpp"
#include "tearables/cloth.hpp"
#include "tearables/controls.hpp"
#include "tearables/events.hpp"
#include "tearables/paper.hpp"
#include "tearables/presets.hpp"
#include "tearables/queries.hpp"
#include "tearables/string.hpp"
#include "tearables/world.hpp"

namespace tearables {

/// Converts between Bullet and the core (the only place that does).
inline Vec3 toCore(const btVector3& v) { return Vec3(v.x(), v.y(), v.z()); }
inline btVector3 toBullet(const Vec3& v) {
    return btVector3(static_cast<btScalar>(v.x()), static_cast<btScalar>(v.y()), static_cast<btScalar>(v.z()));
}

}  // namespace tearables
