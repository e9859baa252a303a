// tearables::BulletWorld, the public face: each call forwards to BulletWorld::Impl
// (bullet_world_impl.hpp), or reads a string's state from the core and converts it to
// Bullet's vectors. Validation is the core's (InvalidInput naming the argument, nothing
// changed), checked before anything is converted or stored.
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

World& BulletWorld::core() { return impl_->core(); }
const World& BulletWorld::core() const { return impl_->core(); }

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
    return impl_->addString(desc);
}

StringId BulletWorld::addString(const StringDesc& desc) { return impl_->addString(desc); }
StringId BulletWorld::addString(const StringDesc& desc, int group, int mask) { return impl_->addString(desc, group, mask); }
void BulletWorld::removeString(StringId id) { impl_->removeString(id); }
void BulletWorld::attach(StringId id, int particle, const btVector3& world_point) { impl_->attach(id, particle, world_point); }
void BulletWorld::attach(StringId id, int particle, btRigidBody& body, const btVector3& local_point) {
    impl_->attach(id, particle, body, local_point);
}
void BulletWorld::detach(StringId id, int particle) { impl_->detach(id, particle); }
void BulletWorld::setVelocities(StringId id, const std::vector<btVector3>& velocities) { impl_->setVelocities(id, velocities); }
void BulletWorld::reel(StringId id, int end, double speed, RestMass mode) { impl_->reel(id, end, speed, mode); }
ClothId BulletWorld::addCloth(const ClothDesc& desc) { return impl_->addCloth(desc); }
ClothId BulletWorld::addCloth(const ClothDesc& desc, int group, int mask) { return impl_->addCloth(desc, group, mask); }
void BulletWorld::removeCloth(ClothId id) { impl_->removeCloth(id); }
void BulletWorld::attachCloth(ClothId id, int vertex, const btVector3& world_point) { impl_->attachCloth(id, vertex, world_point); }
RigidId BulletWorld::bodyId(btRigidBody& body) { return impl_->bodyId(body); }
void BulletWorld::attachCloth(ClothId id, int vertex, btRigidBody& body, const btVector3& local_point) {
    impl_->attachCloth(id, vertex, body, local_point);
}
void BulletWorld::forgetBody(const btRigidBody& body) { impl_->forgetBody(body); }
void BulletWorld::setUserPointer(StringId id, void* user) { impl_->setUserPointer(id, user); }
void BulletWorld::setUserPointer(ClothId id, void* user) { impl_->setUserPointer(id, user); }
void BulletWorld::setUserPointer(PaperId id, void* user) { impl_->setUserPointer(id, user); }
void* BulletWorld::userPointer(StringId id) const { return impl_->userPointer(id); }
void* BulletWorld::userPointer(ClothId id) const { return impl_->userPointer(id); }
void* BulletWorld::userPointer(PaperId id) const { return impl_->userPointer(id); }
PaperId BulletWorld::addPaper(const PaperDesc& desc) { return impl_->addPaper(desc); }
PaperId BulletWorld::addPaper(const PaperDesc& desc, int group, int mask) { return impl_->addPaper(desc, group, mask); }
void BulletWorld::removePaper(PaperId id) { impl_->removePaper(id); }
void BulletWorld::attachPaper(PaperId id, int vertex, const btVector3& world_point) { impl_->attachPaper(id, vertex, world_point); }
void BulletWorld::attachPaper(PaperId id, int vertex, btRigidBody& body, const btVector3& local_point) {
    impl_->attachPaper(id, vertex, body, local_point);
}
void BulletWorld::applyForce(StringId id, int particle, const btVector3& force) { impl_->applyForce(id, particle, force); }
void BulletWorld::applyClothForce(ClothId id, int vertex, const btVector3& force) { impl_->applyClothForce(id, vertex, force); }
void BulletWorld::applyPaperForce(PaperId id, int vertex, const btVector3& force) { impl_->applyPaperForce(id, vertex, force); }
void BulletWorld::movePin(StringId id, int particle, const btVector3& point) { impl_->movePin(id, particle, point); }
bool BulletWorld::cut(StringId id, int segment) {
    const bool cut = impl_->core_->cutSegment(id, segment);
    if (cut) impl_->syncRopeObject(id);  // the gap is open to ray tests at once
    return cut;
}
void BulletWorld::turnEnd(StringId id, int end, double angle) { impl_->turnEnd(id, end, angle); }
double BulletWorld::endTwist(StringId id, int end) const {
    (void)impl_->core_->desc(id);
    return impl_->core_->endTwist(id, end);
}
std::vector<double> BulletWorld::peakTension(StringId id) const { return impl_->peakTension(id); }
void BulletWorld::clearPeakTension(StringId id) { impl_->clearPeakTension(id); }
const std::vector<BulletEvent>& BulletWorld::events() const { return impl_->events(); }
void BulletWorld::clearEvents() { impl_->clearEvents(); }
const std::vector<BulletContact>& BulletWorld::contacts() const { return impl_->contacts(); }
void BulletWorld::setTearCallback(std::function<void(const BulletEvent&)> callback) { impl_->setTearCallback(std::move(callback)); }
void BulletWorld::setContactCallback(std::function<void(const BulletContact&)> callback) {
    impl_->setContactCallback(std::move(callback));
}
const StageTimes& BulletWorld::totalStageTimes() const { return impl_->totalStageTimes(); }
bool BulletWorld::attachedToBullet() const { return impl_->attachedToBullet(); }
void BulletWorld::debugDraw(btIDebugDraw& drawer) const { impl_->debugDraw(drawer); }
const std::string& BulletWorld::lastError() const { return impl_->lastError(); }
void BulletWorld::saveSnapshot(std::ostream& out, const std::vector<const btRigidBody*>& bodies) const {
    impl_->saveSnapshot(out, bodies);
}
void BulletWorld::loadSnapshot(std::istream& in, const std::vector<btRigidBody*>& bodies) { impl_->loadSnapshot(in, bodies); }
void BulletWorld::setRopesRayTestable(bool on) { impl_->setRopesRayTestable(on); }
bool BulletWorld::ropesRayTestable() const { return impl_->ropesRayTestable(); }
const btCollisionObject* BulletWorld::rayObject(StringId id) const { return impl_->rayObject(id); }
std::optional<RopeHit> BulletWorld::ropeHit(const btCollisionObject* object, int child) const {
    return impl_->ropeHit(object, child);
}
std::optional<RopeHit> BulletWorld::ropeHit(const btCollisionObject* object, const btVector3& point) const {
    return impl_->ropeHit(object, point);
}

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
