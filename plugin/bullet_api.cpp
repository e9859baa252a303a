// The Bullet-facing calls beside the step's adapter (bullet_world.cpp): user pointers per
// object, and the contacts and events of each internal step as a Bullet user reads them
// (bodies as btRigidBody*, positions, forces). They convert and look up; the physics, and
// the contact forces, are the core's.
#include "bullet_world_impl.hpp"

#include <btBulletDynamicsCommon.h>

#include <algorithm>
#include <cmath>

namespace tearables {

namespace {

constexpr double kPi = 3.14159265358979323846;

// Sets or reads a pointer kept per id; the core checks the id first (InvalidInput naming
// the argument, "stale id" for a removed object's).
template <class Id>
void setUser(std::map<Id, void*>& users, Id id, void* user) {
    if (user)
        users[id] = user;
    else
        users.erase(id);
}

template <class Id>
void* user(const std::map<Id, void*>& users, Id id) {
    const auto it = users.find(id);
    return it == users.end() ? nullptr : it->second;
}

}  // namespace

void BulletWorld::setUserPointer(StringId id, void* user) {
    (void)impl_->core_->desc(id);
    setUser(impl_->string_users_, id, user);
    impl_->userPointerChanged(id);
}
void BulletWorld::setUserPointer(ClothId id, void* user) {
    (void)impl_->core_->clothDesc(id);
    setUser(impl_->cloth_users_, id, user);
}
void BulletWorld::setUserPointer(PaperId id, void* user) {
    (void)impl_->core_->paperDesc(id);
    setUser(impl_->paper_users_, id, user);
}
void* BulletWorld::userPointer(StringId id) const {
    (void)impl_->core_->desc(id);
    return user(impl_->string_users_, id);
}
void* BulletWorld::userPointer(ClothId id) const {
    (void)impl_->core_->clothDesc(id);
    return user(impl_->cloth_users_, id);
}
void* BulletWorld::userPointer(PaperId id) const {
    (void)impl_->core_->paperDesc(id);
    return user(impl_->paper_users_, id);
}

void BulletWorld::setVelocities(StringId id, const std::vector<btVector3>& velocities) {
    std::vector<Vec3> v;
    v.reserve(velocities.size());
    for (const btVector3& b : velocities) v.push_back(tearables::toCore(b));
    tearables::setVelocities(*impl_->core_, id, v);
}

void BulletWorld::reel(StringId id, int end, double speed, RestMass mode) {
    if (!std::isfinite(speed) || std::abs(speed) > 1000.0) throw InvalidInput("speed", "must be finite, at most 1000 m/s either way");
    tearables::reel(*impl_->core_, id, end, 0.0, mode);  // checks the string, the end and the mode; changes nothing
    if (speed == 0.0)
        impl_->winches_.erase({id, end});
    else
        impl_->winches_[{id, end}] = Impl::Winch{speed, mode};
}

// The core checks the string, the end (0 or -1, pinned to a world point) with a zero turn,
// which changes nothing; the angle waits for the next stepSimulation (drive, bullet_world.cpp).
void BulletWorld::turnEnd(StringId id, int end, double angle) {
    impl_->core_->turnEnd(id, end, 0.0);
    if (!std::isfinite(angle)) throw InvalidInput("angle", "must be finite");
    impl_->turns_[{id, end}].angle += angle;
}

// Winches of strings since removed, or whose end was unpinned, stop.
void BulletWorld::Impl::turnWinches(double h) {
    for (auto it = winches_.begin(); it != winches_.end();) {
        const auto [id, end] = it->first;
        if (!core_->contains(id) || !core_->pinTarget(id, end, nullptr)) {
            it = winches_.erase(it);
            continue;
        }
        tearables::reel(*core_, id, end, it->second.speed * h, it->second.mode);
        ++it;
    }
}

// --- contacts and events as a Bullet user reads them --------------------------------------

const std::vector<BulletContact>& BulletWorld::contacts() const { return impl_->contact_list_; }
void BulletWorld::setTearCallback(std::function<void(const BulletEvent&)> callback) { impl_->on_tear_ = std::move(callback); }
void BulletWorld::setContactCallback(std::function<void(const BulletContact&)> callback) {
    impl_->on_contact_ = std::move(callback);
}

btRigidBody* BulletWorld::Impl::bodyOf(RigidId id) const {
    const auto it = std::lower_bound(body_of_.begin(), body_of_.end(), std::make_pair(id.index, static_cast<btRigidBody*>(nullptr)));
    return it != body_of_.end() && it->first == id.index ? it->second : nullptr;
}

// The body a string's segment j hung from: the glued particle nearest to it along the
// piece it belongs to (the intact segments on either side; the nearer one, the lower index
// of equals).
btRigidBody* BulletWorld::Impl::hangingBody(StringId id, int j) const {
    const StringView v = core_->view(id);
    const int n = static_cast<int>(v.particleCount());
    const auto& broken = *v.broken;
    int left = -1, right = -1;
    for (int p = j; p >= 0; --p) {
        if (gluedBody(*core_, id, p).valid()) { left = p; break; }
        if (p > 0 && broken[p - 1]) break;
    }
    for (int p = j + 1; p < n; ++p) {
        if (gluedBody(*core_, id, p).valid()) { right = p; break; }
        if (p < n - 1 && broken[p]) break;
    }
    int p = left;
    if (right >= 0 && (left < 0 || right - (j + 1) < j - left)) p = right;
    return p < 0 ? nullptr : bodyOf(gluedBody(*core_, id, p));
}

// Where and on what an event of the last internal step happened.
void BulletWorld::Impl::describe(BulletEvent& e) const {
    if (!e.string.valid() || !core_->contains(e.string)) return;
    const StringView v = core_->view(e.string);
    const auto& x = *v.positions;
    if (e.segment >= 0 && static_cast<std::size_t>(e.segment) < v.segmentCount()) {
        e.position = tearables::toBullet(0.5 * (x[e.segment] + x[e.segment + 1]));
        if ((e.type == EventType::Tear || e.type == EventType::Yield) && e.cause == EventCause::Tension) {
            const double r0 = core_->desc(e.string).radius;
            e.force = e.stress * kPi * r0 * r0;
        }
    } else if (e.particle >= 0 && static_cast<std::size_t>(e.particle) < v.particleCount()) {
        e.position = tearables::toBullet(x[e.particle]);
    }
    if (e.type == EventType::Overlap) e.body = bodyOf(e.rigid);
    if (e.type != EventType::Tear || e.segment < 0) return;
    double pressed = 0.0;
    for (const ContactForce& c : contact_forces_)
        if (c.string == e.string && static_cast<int>(c.segment) == e.segment && c.normal_force > pressed) {
            if (btRigidBody* body = bodyOf(c.body)) {
                e.body = body;
                pressed = c.normal_force;
            }
        }
    if (!e.body) e.body = hangingBody(e.string, e.segment);
}

// After each internal step: its contacts with the forces, its events (a string's yields
// merged), then the callbacks.
void BulletWorld::Impl::reportStep(double h) {
    body_of_.clear();
    for (const auto& [body, id] : proxies_) body_of_.emplace_back(id.index, const_cast<btRigidBody*>(body));
    std::sort(body_of_.begin(), body_of_.end());
    lastContactForces(*core_, contact_forces_);
    contact_list_.clear();
    for (const ContactForce& f : contact_forces_) {
        BulletContact c;
        c.body = bodyOf(f.body);
        if (!c.body) continue;
        c.string = f.string;
        c.segment = static_cast<int>(f.segment);
        c.s = f.s;
        c.position = tearables::toBullet(f.point);
        c.normal = tearables::toBullet(f.normal);
        c.normal_force = f.normal_force;
        const Vec3 on_body = -(f.normal_force * f.normal + f.friction_force);
        c.force = tearables::toBullet(on_body);
        c.impulse = tearables::toBullet(on_body * h);
        contact_list_.push_back(c);
    }
    const std::size_t first = events_.size();
    for (const Event& e : core_->events()) {
        BulletEvent b;
        static_cast<Event&>(b) = e;
        describe(b);
        if (e.type == EventType::Yield && e.string.valid()) {
            const auto same = std::find_if(events_.begin() + static_cast<std::ptrdiff_t>(first), events_.end(), [&](const BulletEvent& o) {
                return o.type == EventType::Yield && o.string == e.string && o.cause == e.cause;
            });
            if (same != events_.end()) {
                const int count = same->count + 1;
                if (e.stress > same->stress) *same = b;
                same->count = count;
                continue;
            }
        }
        events_.push_back(b);
    }
    if (on_contact_)
        for (const BulletContact& c : contact_list_) on_contact_(c);
    if (on_tear_)
        for (std::size_t k = first; k < events_.size(); ++k)
            if (events_[k].type == EventType::Tear) on_tear_(events_[k]);
}

}  // namespace tearables
