// Ropes in Bullet's own queries: each string is one btCollisionObject in the Bullet world,
// a btCompoundShape of one capsule per intact segment (radius the string's, from particle j
// to particle j + 1), moved to the particles at the end of each stepSimulation. Bullet's
// btCollisionWorld::rayTest then meets ropes as it meets crates; for a compound it reports
// the child it hit in LocalShapeInfo::m_triangleIndex (btCollisionWorld::rayTestSingleInternal),
// and each object keeps which segment each child is.
//
// A child is a SegmentShape, not a btCapsuleShape: Bullet casts a ray at a convex shape
// iteratively (btSubsimplexConvexCast, stopping once within sqrt(1e-4) m in single
// precision), which on a 1 cm rope reports hits up to 0.5 cm outside it and places them up
// to half a radius off (docs/facade.md). A concave shape gets the ray itself instead
// (processAllTriangles with a btTriangleRaycastCallback), so the capsule is hit exactly
// (rayCapsule, the core's ray test); other queries (convexSweepTest, contactTest) get the
// triangles of a prism around the capsule.
//
// The object takes no part in the simulation:
//  - it is static (CF_STATIC_OBJECT): no simulation island, not in the solver's bodies,
//    never put to sleep (Bullet's activation pass reads rigid bodies only);
//  - the world's pair cache is given a filter (btOverlapFilterCallback, if it has none)
//    that refuses every pair with a rope object: Bullet's pairs are those of the world
//    without ropes' objects (their order may still differ where bodies touch each other:
//    the broadphase's tree holds the objects' leaves too; README, "Ray tests");
//  - checkCollideWithOverride answers false to every object (m_checkCollideWith = 1), so
//    where a filter of the user's lets a pair through, btCollisionDispatcher::needsCollision
//    still refuses it: no collision algorithm, manifold or contact is ever made for it;
//  - CF_NO_CONTACT_RESPONSE: the plugin's own broadphase search (bodiesIn) and Bullet's
//    character controller skip it; it is not a btRigidBody, so nothing that upcasts the
//    world's objects (island_claim.cpp, the contact provider) sees it either;
//  - CF_DISABLE_VISUALIZE_OBJECT: debugDraw() draws ropes already.
// Its broadphase filter is the string's (addString(desc, group, mask)), so a ray's own
// group and mask select ropes as they select bodies.
#include "bullet_world_impl.hpp"

#include "tearables/queries.hpp"

#include <BulletCollision/CollisionShapes/btConcaveShape.h>
#include <BulletCollision/CollisionShapes/btTriangleCallback.h>
#include <BulletCollision/NarrowPhaseCollision/btRaycastCallback.h>
#include <btBulletDynamicsCommon.h>

#include <algorithm>
#include <cmath>
#include <limits>

namespace tearables {

namespace {

/// How far a segment's box in the compound's tree reaches past the segment's capsule, m: a
/// segment that moves less than this between steps costs no update of the tree (btDbvt's
/// update with a margin; Bullet's broadphase grows its proxies' boxes by the same 5 cm,
/// DBVT_BP_MARGIN); a ray passing that close to a rope tests a few more capsules.
constexpr btScalar kLeafMargin = btScalar(0.05);

/// Sides of the prism that stands for a capsule in queries other than ray tests.
constexpr int kPrismSides = 8;

/// One segment: the capsule of radius r around the segment from a to b, in the compound's
/// frame (the object's; it stays at the origin, so this is the world's): the child's own
/// transform stays the identity, and moving a segment is setting its two points.
class SegmentShape final : public btConcaveShape {
public:
    explicit SegmentShape(int child) : child_(child) { m_shapeType = FAST_CONCAVE_MESH_PROXYTYPE; }
    void set(const btVector3& a, const btVector3& b, btScalar radius) {
        a_ = a;
        b_ = b;
        radius_ = radius;
    }

    void getAabb(const btTransform& t, btVector3& lo, btVector3& hi) const override {
        const btVector3 a = t * a_, b = t * b_, reach(radius_, radius_, radius_);
        lo = a;
        lo.setMin(b);
        hi = a;
        hi.setMax(b);
        lo -= reach;
        hi += reach;
    }

    // A ray (btCollisionWorld::rayTestSingleInternal's bridge, in this shape's frame): the
    // exact entry into the capsule, reported as Bullet's triangle ray casts report theirs,
    // with the child index as the triangle. Anything else: the prism's triangles.
    void processAllTriangles(btTriangleCallback* callback, const btVector3& lo, const btVector3& hi) const override {
        if (auto* ray = dynamic_cast<btTriangleRaycastCallback*>(callback)) {
            castRay(*ray);
            return;
        }
        btVector3 box_lo, box_hi;
        getAabb(btTransform::getIdentity(), box_lo, box_hi);
        if (box_lo.x() > hi.x() || box_lo.y() > hi.y() || box_lo.z() > hi.z() || box_hi.x() < lo.x() ||
            box_hi.y() < lo.y() || box_hi.z() < lo.z())
            return;
        emitPrism(*callback);
    }

    void setLocalScaling(const btVector3&) override {}  // a rope is not scaled
    const btVector3& getLocalScaling() const override { return unit_scale_; }
    void calculateLocalInertia(btScalar, btVector3& inertia) const override { inertia.setValue(0, 0, 0); }
    const char* getName() const override { return "tearables rope segment"; }

private:
    void castRay(btTriangleRaycastCallback& ray) const {
        const Vec3 from = toCore(ray.m_from), to = toCore(ray.m_to), a = toCore(a_), b = toCore(b_);
        const auto hit = rayCapsule(from, to, a, b, static_cast<double>(radius_));
        if (!hit || !(hit->first < static_cast<double>(ray.m_hitFraction))) return;
        const Vec3 point = from + hit->first * (to - from);
        const Vec3 out = point - (a + hit->second * (b - a));
        const Vec3 normal = out.norm() > 0.0 ? Vec3(out.normalized()) : Vec3(-(to - from).normalized());
        ray.m_hitFraction = ray.reportHit(toBullet(normal), static_cast<btScalar>(hit->first), -1, child_);
    }

    // A right prism of kPrismSides sides around the segment, circumscribing the capsule:
    // its side faces at the radius (corners at r / cos(pi / n)), its ends r past the
    // segment's. Its frame: the segment's direction and two normals (btPlaneSpace1).
    void emitPrism(btTriangleCallback& callback) const {
        constexpr double kPi = 3.14159265358979323846;
        btVector3 axis = b_ - a_;
        const btScalar length = axis.length();
        axis = length > btScalar(0) ? axis / length : btVector3(0, 1, 0);
        btVector3 u, w;
        btPlaneSpace1(axis, u, w);
        const double corner = static_cast<double>(radius_) / std::cos(kPi / kPrismSides);
        const btVector3 low = a_ - axis * radius_, high = b_ + axis * radius_;
        btVector3 ring[kPrismSides];
        for (int k = 0; k < kPrismSides; ++k) {
            const double angle = 2.0 * kPi * k / kPrismSides;
            ring[k] = u * static_cast<btScalar>(corner * std::cos(angle)) + w * static_cast<btScalar>(corner * std::sin(angle));
        }
        btVector3 tri[3];
        for (int k = 0; k < kPrismSides; ++k) {
            const btVector3 &p = ring[k], &q = ring[(k + 1) % kPrismSides];
            tri[0] = low + p, tri[1] = low + q, tri[2] = high + q;
            callback.processTriangle(tri, 0, child_);
            tri[0] = low + p, tri[1] = high + q, tri[2] = high + p;
            callback.processTriangle(tri, 0, child_);
        }
        for (int k = 1; k + 1 < kPrismSides; ++k) {
            tri[0] = high + ring[0], tri[1] = high + ring[k + 1], tri[2] = high + ring[k];
            callback.processTriangle(tri, 0, child_);
            tri[0] = low + ring[0], tri[1] = low + ring[k], tri[2] = low + ring[k + 1];
            callback.processTriangle(tri, 0, child_);
        }
    }

    int child_;
    btVector3 a_{0, 0, 0}, b_{0, 0, 0};
    btScalar radius_ = 0;
    btVector3 unit_scale_{1, 1, 1};
};

/// The user pointer of every rope object's shape: how the pair filter tells a rope object
/// from a body without a dynamic_cast on every pair test. The shape is the plugin's, so its
/// user pointer is too (the object's user pointer and indices are the user's to read:
/// docs/facade.md, "Identity").
const char kRopeShapeTag = 0;

/// A compound whose children are moved in place: a child's leaf in the tree is moved only
/// when its capsule left the leaf's grown box (updateChildTransform re-inserts the leaf
/// whenever the child moves at all), and the bounds of the whole are set from the
/// capsules' boxes.
class RopeCompound final : public btCompoundShape {
public:
    explicit RopeCompound(int children) : btCompoundShape(true, children) {
        setUserPointer(const_cast<char*>(&kRopeShapeTag));
    }
    void moveChild(int k, const btVector3& lo, const btVector3& hi) {
        btDbvtVolume box = btDbvtVolume::FromMM(lo, hi);
        if (m_dynamicAabbTree && m_children[k].m_node) m_dynamicAabbTree->update(m_children[k].m_node, box, kLeafMargin);
    }
    void setLocalBounds(const btVector3& lo, const btVector3& hi) {
        m_localAabbMin = lo;
        m_localAabbMax = hi;
    }
};

}  // namespace

class BulletWorld::Impl::RopeObject final : public btCollisionObject {
public:
    RopeObject(const Impl& owner, StringId id) : owner_(owner), id_(id) {
        m_checkCollideWith = 1;  // ask checkCollideWithOverride about every pair
        setCollisionFlags(CF_STATIC_OBJECT | CF_NO_CONTACT_RESPONSE | CF_DISABLE_VISUALIZE_OBJECT);
        setUserIndex(static_cast<int>(id.index));
        setUserIndex2(static_cast<int>(id.generation));
        compound_ = std::make_unique<RopeCompound>(0);
        setCollisionShape(compound_.get());
    }
    bool checkCollideWithOverride(const btCollisionObject*) const override { return false; }

    const Impl& owner() const { return owner_; }
    StringId id() const { return id_; }
    /// The segment of each compound child, ascending.
    const std::vector<int>& segments() const { return segments_; }

    /// Puts one capsule per intact segment of `v` where its particles are. The children are
    /// rebuilt when the intact segments changed (a tear, a cut, reeling); otherwise moved
    /// in place.
    void follow(const StringView& v) {
        const auto& x = *v.positions;
        const auto& broken = *v.broken;
        bool usable = !v.frozen && std::isfinite(v.radius) && v.radius > 0.0;
        for (std::size_t p = 0; usable && p < x.size(); ++p) usable = x[p].allFinite();
        intact_.clear();
        if (usable)
            for (std::size_t j = 0; j < broken.size(); ++j)
                if (!broken[j]) intact_.push_back(static_cast<int>(j));
        radius_ = static_cast<btScalar>(v.radius);
        if (intact_ != segments_) rebuild();
        btVector3 lo(BT_LARGE_FLOAT, BT_LARGE_FLOAT, BT_LARGE_FLOAT), hi = -lo;
        for (std::size_t k = 0; k < segments_.size(); ++k) {
            SegmentShape& segment = *capsules_[k];
            segment.set(toBullet(x[segments_[k]]), toBullet(x[segments_[k] + 1]), radius_);
            btVector3 box_lo, box_hi;
            segment.getAabb(btTransform::getIdentity(), box_lo, box_hi);
            compound_->moveChild(static_cast<int>(k), box_lo, box_hi);
            lo.setMin(box_lo);
            hi.setMax(box_hi);
        }
        if (segments_.empty()) lo = hi = btVector3(0, 0, 0);
        compound_->setLocalBounds(lo, hi);
    }

private:
    void rebuild() {
        segments_ = intact_;
        while (capsules_.size() < segments_.size())
            capsules_.push_back(std::make_unique<SegmentShape>(static_cast<int>(capsules_.size())));
        // A fresh compound: its children and their tree made in segment order.
        auto fresh = std::make_unique<RopeCompound>(static_cast<int>(segments_.size()));
        for (std::size_t k = 0; k < segments_.size(); ++k) fresh->addChildShape(btTransform::getIdentity(), capsules_[k].get());
        setCollisionShape(fresh.get());
        compound_ = std::move(fresh);
    }

    const Impl& owner_;
    StringId id_;
    btScalar radius_ = 0;
    std::vector<int> segments_, intact_;
    std::unique_ptr<RopeCompound> compound_;
    std::vector<std::unique_ptr<SegmentShape>> capsules_;  // per child: child k is capsules_[k]
};

namespace {

/// Whether `object` is a rope object (of any BulletWorld): its shape carries the tag.
bool isRopeObject(const btCollisionObject* object) {
    const btCollisionShape* shape = object ? object->getCollisionShape() : nullptr;
    return shape && shape->getUserPointer() == &kRopeShapeTag;
}

}  // namespace

/// Refuses every broadphase pair with a rope object (of any BulletWorld), so that Bullet's
/// pair cache holds the pairs it would hold without them (a pair made and dropped again
/// reorders the cache's others). Other pairs get Bullet's own rule
/// (btHashedOverlappingPairCache::needsBroadphaseCollision).
struct BulletWorld::Impl::RopePairFilter final : btOverlapFilterCallback {
    static bool isRope(const btBroadphaseProxy* proxy) {
        return isRopeObject(static_cast<const btCollisionObject*>(proxy->m_clientObject));
    }
    bool needBroadphaseCollision(btBroadphaseProxy* a, btBroadphaseProxy* b) const override {
        if (isRope(a) || isRope(b)) return false;
        return (a->m_collisionFilterGroup & b->m_collisionFilterMask) != 0 &&
               (b->m_collisionFilterGroup & a->m_collisionFilterMask) != 0;
    }
};

// One filter for every world, never freed (it has no state): a world may outlive the
// plugin that installed it, and then keeps Bullet's rule through it.
void BulletWorld::Impl::installPairFilter() {
    static RopePairFilter filter;
    btOverlappingPairCache* cache = world_->getPairCache();
    if (cache && !cache->getOverlapFilterCallback()) cache->setOverlapFilterCallback(&filter);
}

BulletWorld::Impl::RopeObjectSlot::RopeObjectSlot() = default;
BulletWorld::Impl::RopeObjectSlot::RopeObjectSlot(RopeObjectSlot&&) noexcept = default;
BulletWorld::Impl::RopeObjectSlot& BulletWorld::Impl::RopeObjectSlot::operator=(RopeObjectSlot&&) noexcept = default;
BulletWorld::Impl::RopeObjectSlot::~RopeObjectSlot() = default;

void BulletWorld::Impl::syncRopeObject(StringId id) {
    if (!rope_objects_on_ || !attachedToBullet() || !core_->contains(id)) return;
    RopeObjectSlot& slot = rope_objects_[id];
    if (!slot.object) {
        slot.object = std::make_unique<RopeObject>(*this, id);
        const auto user = string_users_.find(id);
        slot.object->setUserPointer(user == string_users_.end() ? nullptr : user->second);
        const auto filter = string_filters_.find(id.index);
        const Filter f = filter == string_filters_.end() ? Filter{} : filter->second;
        slot.object->follow(core_->view(id));
        world_->addCollisionObject(slot.object.get(), f.group, f.mask);
        return;
    }
    slot.object->follow(core_->view(id));
    // Its bounds in the broadphase now, for the ray tests the user makes before the next step.
    if (slot.object->getBroadphaseHandle()) world_->updateSingleAabb(slot.object.get());
}

void BulletWorld::Impl::dropRopeObject(StringId id) {
    const auto it = rope_objects_.find(id);
    if (it == rope_objects_.end()) return;
    // A handle means the object is in the Bullet world (~btCollisionWorld clears it).
    if (it->second.object->getBroadphaseHandle()) world_->removeCollisionObject(it->second.object.get());
    rope_objects_.erase(it);
}

// After a step, and after changes the core made on its own (strings removed through
// core(), a snapshot loaded): objects of strings gone are dropped, the others follow.
void BulletWorld::Impl::syncRopeObjects() {
    if (!attachedToBullet()) return;  // ~btCollisionWorld has let go of every object
    for (auto it = rope_objects_.begin(); it != rope_objects_.end();) {
        const StringId id = it->first;
        ++it;
        if (!rope_objects_on_ || !core_->contains(id)) dropRopeObject(id);
    }
    if (!rope_objects_on_) return;
    for (const StringId id : core_->strings()) syncRopeObject(id);
}

void BulletWorld::setRopesRayTestable(bool on) {
    impl_->rope_objects_on_ = on;
    impl_->syncRopeObjects();
}

void BulletWorld::Impl::userPointerChanged(StringId id) {
    const auto it = rope_objects_.find(id);
    if (it == rope_objects_.end()) return;
    const auto user = string_users_.find(id);
    it->second.object->setUserPointer(user == string_users_.end() ? nullptr : user->second);
}

void BulletWorld::Impl::removeRopeObjectsFromWorld() {
    for (auto& [id, slot] : rope_objects_)
        if (slot.object->getBroadphaseHandle()) world_->removeCollisionObject(slot.object.get());
}

const btCollisionObject* BulletWorld::rayObject(StringId id) const {
    (void)impl_->core_->desc(id);  // InvalidInput("string") for an unknown or stale id
    const auto it = impl_->rope_objects_.find(id);
    return it == impl_->rope_objects_.end() ? nullptr : it->second.object.get();
}

// The object must be one of this plugin's, for a live string whose segment is still
// intact (a change made through core() reaches the objects at the next step).
std::optional<RopeHit> BulletWorld::ropeHit(const btCollisionObject* object, int child) const {
    const auto* rope = dynamic_cast<const Impl::RopeObject*>(object);
    if (!rope || &rope->owner() != impl_.get() || !impl_->core_->contains(rope->id())) return std::nullopt;
    const auto& segments = rope->segments();
    if (child < 0 || static_cast<std::size_t>(child) >= segments.size()) return std::nullopt;
    const int segment = segments[child];
    const StringView v = impl_->core_->view(rope->id());
    if (static_cast<std::size_t>(segment) >= v.segmentCount() || (*v.broken)[segment]) return std::nullopt;
    return RopeHit{rope->id(), segment};
}

// The capsule whose surface is nearest the point: |distance to the axis - r| least.
std::optional<RopeHit> BulletWorld::ropeHit(const btCollisionObject* object, const btVector3& point) const {
    const auto* rope = dynamic_cast<const Impl::RopeObject*>(object);
    if (!rope || &rope->owner() != impl_.get() || !impl_->core_->contains(rope->id())) return std::nullopt;
    const Vec3 at = toCore(point);
    if (!at.allFinite()) throw InvalidInput("point", "must be finite");
    const StringView v = impl_->core_->view(rope->id());
    const auto& x = *v.positions;
    std::optional<RopeHit> best;
    double best_gap = std::numeric_limits<double>::infinity();
    for (std::size_t j = 0; j < v.segmentCount(); ++j) {
        if ((*v.broken)[j]) continue;
        const Vec3 axis = x[j + 1] - x[j];
        const double l2 = axis.squaredNorm();
        const double s = l2 > 0.0 ? std::clamp((at - x[j]).dot(axis) / l2, 0.0, 1.0) : 0.0;
        const double gap = std::fabs((at - (x[j] + s * axis)).norm() - v.radius);
        if (gap < best_gap) {
            best_gap = gap;
            best = RopeHit{rope->id(), static_cast<int>(j)};
        }
    }
    return best;
}

}  // namespace tearables
