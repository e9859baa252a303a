// The Bullet adapter: converts and forwards. Bullet calls Action::updateAction once per
// internal step, after it has integrated the rigid bodies; we copy the bodies that strings
// hold into the core's proxies, step the core, and write the bodies' corrected poses and
// velocities back.
#include "tearables/bullet.hpp"

#include <BulletCollision/CollisionShapes/btEmptyShape.h>
#include <btBulletDynamicsCommon.h>

#include <exception>

namespace tearables {

namespace {

Quat toCore(const btQuaternion& q) { return Quat(q.w(), q.x(), q.y(), q.z()); }
btQuaternion toBullet(const Quat& q) {
    return btQuaternion(static_cast<btScalar>(q.x()), static_cast<btScalar>(q.y()), static_cast<btScalar>(q.z()),
                        static_cast<btScalar>(q.w()));
}

}  // namespace

// The per-substep callback, plus a sentinel collision object that tells us whether the
// Bullet world still exists: ~btCollisionWorld clears the broadphase handle of every
// object it still holds, and the sentinel's memory is ours, so reading it stays safe.
class BulletWorld::Action : public btActionInterface {
public:
    explicit Action(BulletWorld& owner) : owner_(owner), shape_() {
        sentinel_.setCollisionShape(&shape_);
        sentinel_.setCollisionFlags(btCollisionObject::CF_STATIC_OBJECT | btCollisionObject::CF_NO_CONTACT_RESPONSE);
    }
    void updateAction(btCollisionWorld*, btScalar time_step) override { owner_.substep(static_cast<double>(time_step)); }
    void debugDraw(btIDebugDraw*) override {}

    btCollisionObject& sentinel() { return sentinel_; }
    bool inWorld() const { return sentinel_.getBroadphaseHandle() != nullptr; }

private:
    BulletWorld& owner_;
    btEmptyShape shape_;
    btCollisionObject sentinel_;
};

BulletWorld::BulletWorld(btDiscreteDynamicsWorld& world, const WorldSettings& settings)
    : world_(&world), core_(std::make_unique<World>(settings)), action_(std::make_unique<Action>(*this)) {
    // Group and mask 0: the sentinel never pairs with anything nor answers ray tests.
    world_->addCollisionObject(&action_->sentinel(), 0, 0);
    world_->addAction(action_.get());
}

BulletWorld::~BulletWorld() {
    if (attachedToBullet()) {
        world_->removeAction(action_.get());
        world_->removeCollisionObject(&action_->sentinel());
    }
}

bool BulletWorld::attachedToBullet() const { return action_->inWorld(); }
World& BulletWorld::core() { return *core_; }
const World& BulletWorld::core() const { return *core_; }
StringId BulletWorld::addString(const StringDesc& desc) { return core_->addString(desc); }
void BulletWorld::removeString(StringId id) { core_->removeString(id); }
const std::vector<Event>& BulletWorld::events() const { return events_; }
void BulletWorld::clearEvents() { events_.clear(); }
const StageTimes& BulletWorld::totalStageTimes() const { return total_; }
const std::string& BulletWorld::lastError() const { return last_error_; }

void BulletWorld::attach(StringId id, int particle, const btVector3& world_point) {
    core_->attachToPoint(id, particle, toCore(world_point));
}

RigidId BulletWorld::proxyFor(btRigidBody& body) {
    auto it = proxies_.find(&body);
    if (it != proxies_.end()) return it->second;
    RigidState state;
    state.position = toCore(body.getCenterOfMassPosition());
    state.orientation = toCore(body.getOrientation());
    const RigidId id = core_->addRigid(state);
    proxies_.emplace(&body, id);
    return id;
}

void BulletWorld::attach(StringId id, int particle, btRigidBody& body, const btVector3& local_point) {
    if (!body.getBroadphaseHandle()) throw InvalidInput("body", "is not in the Bullet world");
    if (!core_->contains(id)) throw InvalidInput("string", "no such string");
    core_->resolveParticle(id, particle);  // validates before anything is created
    core_->attachToRigid(id, particle, proxyFor(body), toCore(local_point));
}

void BulletWorld::detach(StringId id, int particle) { core_->detach(id, particle); }

void BulletWorld::forgetBody(const btRigidBody& body) {
    auto it = proxies_.find(&body);
    if (it == proxies_.end()) return;
    core_->removeRigid(it->second);
    proxies_.erase(it);
}

void BulletWorld::substep(double h) {
    try {
        core_->settings().gravity = toCore(world_->getGravity());
        // Bodies in: drop those that left the world, copy the others' state.
        for (auto it = proxies_.begin(); it != proxies_.end();) {
            btRigidBody* body = const_cast<btRigidBody*>(it->first);
            if (!body->getBroadphaseHandle()) {
                core_->removeRigid(it->second);
                it = proxies_.erase(it);
                continue;
            }
            if (!core_->rigidInUse(it->second)) {  // no string holds it any more
                core_->removeRigid(it->second);
                it = proxies_.erase(it);
                continue;
            }
            RigidState& s = core_->rigid(it->second);
            s.position = toCore(body->getCenterOfMassPosition());
            s.orientation = toCore(body->getOrientation());
            s.linear_velocity = toCore(body->getLinearVelocity());
            s.angular_velocity = toCore(body->getAngularVelocity());
            const bool dynamic = !body->isStaticOrKinematicObject() && body->getInvMass() > 0;
            s.inverse_mass = dynamic ? body->getInvMass() : 0.0;
            s.inverse_inertia_local = dynamic ? Mat3(toCore(body->getInvInertiaDiagLocal()).asDiagonal()) : Mat3::Zero();
            s.awake = body->isActive();
            ++it;
        }

        core_->step(h);

        // Bodies out: the strings' corrections as new poses and velocities.
        for (const auto& [key, id] : proxies_) {
            btRigidBody* body = const_cast<btRigidBody*>(key);
            const RigidState& s = core_->rigid(id);
            if (s.inverse_mass <= 0.0) continue;
            if (!s.awake) {  // it was immovable this step; wake it so that it hangs on its strings
                body->activate();
                continue;
            }
            body->setLinearVelocity(tearables::toBullet(s.linear_velocity));
            body->setAngularVelocity(tearables::toBullet(s.angular_velocity));
            btTransform xf(toBullet(s.orientation), tearables::toBullet(s.position));
            body->setCenterOfMassTransform(xf);
            body->activate();  // a held body stays awake so that its strings' tension stays true
        }
        const std::vector<Event>& ev = core_->events();
        events_.insert(events_.end(), ev.begin(), ev.end());
        total_ += core_->lastStageTimes();
    } catch (const std::exception& e) {
        last_error_ = e.what();  // never throw into Bullet's step
    } catch (...) {
        last_error_ = "unknown error in tearables step";
    }
}

}  // namespace tearables
