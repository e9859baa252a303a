// tearables::BulletWorld's reads and small calls: a string's, a cloth's and a sheet's state
// read from the core and converted to Bullet's vectors. The other calls are defined beside
// the state they use (bullet_world.cpp, bullet_api.cpp, bullet_rays.cpp,
// bullet_snapshot.cpp); BulletWorld::Impl (bullet_world_impl.hpp) holds the data.
// Validation is the core's (InvalidInput naming the argument, nothing changed), checked
// before anything is converted or stored.
#include "bullet_world_impl.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace tearables {

namespace {

// The core's view of a live string (InvalidInput("string") for an unknown or stale id).
StringView liveView(const World& core, StringId id) {
    (void)core.desc(id);
    return core.view(id);
}

std::vector<btVector3> toBulletAll(const std::vector<Vec3>& v) {
    std::vector<btVector3> out;
    out.reserve(v.size());
    for (const Vec3& x : v) out.push_back(tearables::toBullet(x));
    return out;
}

}  // namespace

BulletWorld::BulletWorld(btDiscreteDynamicsWorld& world) : BulletWorld(world, WorldSettings{}) {}
BulletWorld::BulletWorld(btDiscreteDynamicsWorld& world, const WorldSettings& settings)
    : impl_(std::make_unique<Impl>(world, settings)) {}
BulletWorld::~BulletWorld() = default;

// --- building ropes ---------------------------------------------------------------------

StringDesc BulletWorld::ropeBetween(const btVector3& a, const btVector3& b, double length, int segments) {
    return StringDesc::between(toCore(a), toCore(b), length, segments);
}

StringId BulletWorld::addRope(const btVector3& a, const btVector3& b, double length, int segments, const std::string& preset) {
    const MaterialPreset* p = findMaterialPreset(preset);
    if (!p) (void)materialPreset(preset);  // throws InvalidInput("preset") listing the known names
    StringDesc desc = ropeBetween(a, b, length, segments);
    desc.material = p->material;
    desc.radius = p->radius;
    desc.density = p->density;
    return addString(desc);
}

bool BulletWorld::cut(StringId id, int segment) {
    const bool cut = impl_->core_->cutSegment(id, segment);
    if (cut) impl_->syncRopeObject(id);  // the gap is open to ray tests at once
    return cut;
}
double BulletWorld::endTwist(StringId id, int end) const {
    (void)impl_->core_->desc(id);
    return impl_->core_->endTwist(id, end);
}
// The step uses these two as well (the plugin's action: its drawing, Bullet's liveness).
bool BulletWorld::attachedToBullet() const { return impl_->attachedToBullet(); }
void BulletWorld::debugDraw(btIDebugDraw& drawer) const { impl_->debugDraw(drawer); }
bool BulletWorld::ropesRayTestable() const { return impl_->rope_objects_on_; }

// --- reading a cloth or a sheet ----------------------------------------------------------
// The core's views (InvalidInput("cloth"/"paper") for an unknown or stale id), converted.

std::size_t BulletWorld::vertexCount(ClothId id) const { return impl_->core_->viewCloth(id).vertexCount(); }
std::size_t BulletWorld::vertexCount(PaperId id) const { return impl_->core_->viewPaper(id).vertexCount(); }
std::vector<btVector3> BulletWorld::positions(ClothId id) const { return toBulletAll(*impl_->core_->viewCloth(id).positions); }
std::vector<btVector3> BulletWorld::positions(PaperId id) const { return toBulletAll(*impl_->core_->viewPaper(id).positions); }
std::vector<btVector3> BulletWorld::velocities(ClothId id) const { return toBulletAll(*impl_->core_->viewCloth(id).velocities); }
std::vector<btVector3> BulletWorld::velocities(PaperId id) const { return toBulletAll(*impl_->core_->viewPaper(id).velocities); }

std::vector<BulletYarn> BulletWorld::yarns(ClothId id) const {
    const ClothView v = impl_->core_->viewCloth(id);
    std::vector<BulletYarn> out;
    out.reserve(v.edgeCount());
    for (std::size_t e = 0; e < v.edgeCount(); ++e)
        if (!(*v.broken)[e]) {
            const auto& edge = (*v.edges)[e];
            out.push_back(BulletYarn{static_cast<int>(edge[0]), static_cast<int>(edge[1]), static_cast<int>(e), (*v.tension)[e]});
        }
    return out;
}

namespace {

std::vector<std::array<int, 3>> toIntTriangles(const std::vector<std::array<std::uint32_t, 3>>& triangles) {
    std::vector<std::array<int, 3>> out;
    out.reserve(triangles.size());
    for (const auto& t : triangles) out.push_back({static_cast<int>(t[0]), static_cast<int>(t[1]), static_cast<int>(t[2])});
    return out;
}

}  // namespace

std::vector<std::array<int, 3>> BulletWorld::triangles(ClothId id) const { return toIntTriangles(clothFaces(impl_->core_->viewCloth(id))); }
std::vector<std::array<int, 3>> BulletWorld::triangles(PaperId id) const { return toIntTriangles(*impl_->core_->viewPaper(id).triangles); }

std::size_t BulletWorld::tornCount(ClothId id) const {
    const ClothView v = impl_->core_->viewCloth(id);
    return static_cast<std::size_t>(std::count_if(v.broken->begin(), v.broken->end(), [](std::uint8_t b) { return b != 0; }));
}
std::size_t BulletWorld::tornCount(PaperId id) const { return static_cast<std::size_t>(impl_->core_->viewPaper(id).counters.tears); }

// --- reading a string -------------------------------------------------------------------

std::size_t BulletWorld::particleCount(StringId id) const { return liveView(*impl_->core_, id).particleCount(); }
std::size_t BulletWorld::segmentCount(StringId id) const { return liveView(*impl_->core_, id).segmentCount(); }
std::vector<btVector3> BulletWorld::positions(StringId id) const { return toBulletAll(*liveView(*impl_->core_, id).positions); }
std::vector<btVector3> BulletWorld::velocities(StringId id) const { return toBulletAll(*liveView(*impl_->core_, id).velocities); }

btVector3 BulletWorld::position(StringId id, int particle) const {
    const StringView v = liveView(*impl_->core_, id);
    return tearables::toBullet((*v.positions)[impl_->core_->resolveParticle(id, particle)]);
}

std::vector<double> BulletWorld::tensions(StringId id) const { return *liveView(*impl_->core_, id).tension; }

std::vector<bool> BulletWorld::brokenSegments(StringId id) const {
    const auto& broken = *liveView(*impl_->core_, id).broken;
    return std::vector<bool>(broken.begin(), broken.end());
}

std::vector<BulletWorld::Piece> BulletWorld::pieces(StringId id) const {
    const StringView v = liveView(*impl_->core_, id);
    std::vector<Piece> out;
    Piece piece;
    for (std::size_t j = 0; j < v.segmentCount(); ++j)
        if ((*v.broken)[j]) {
            piece.last = static_cast<int>(j);
            out.push_back(piece);
            piece.first = static_cast<int>(j) + 1;
        }
    piece.last = static_cast<int>(v.particleCount()) - 1;
    out.push_back(piece);
    return out;
}

double BulletWorld::length(StringId id) const {
    const StringView v = liveView(*impl_->core_, id);
    const auto& x = *v.positions;
    double sum = 0.0;
    for (std::size_t j = 0; j < v.segmentCount(); ++j)
        if (!(*v.broken)[j]) sum += (x[j + 1] - x[j]).norm();
    return sum;
}

double BulletWorld::restLength(StringId id) const {
    const StringView v = liveView(*impl_->core_, id);
    double sum = 0.0;
    for (std::size_t j = 0; j < v.segmentCount(); ++j)
        if (!(*v.broken)[j]) sum += (*v.rest_length)[j];
    return sum;
}

double BulletWorld::mass(StringId id) const {
    const StringView v = liveView(*impl_->core_, id);
    double sum = 0.0;
    for (const double m : *v.masses) sum += m;
    return sum;
}

bool BulletWorld::isAttached(StringId id, int particle) const {
    (void)impl_->core_->desc(id);
    return impl_->core_->isAttached(id, particle);
}

}  // namespace tearables
