// The Bullet-facing calls that only keep or look up what the user gave: user pointers per
// object. The physics stays in the core; the step's adapter is bullet_world.cpp.
#include "tearables/bullet.hpp"

namespace tearables {

namespace {

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
    (void)core_->desc(id);
    setUser(string_users_, id, user);
}
void BulletWorld::setUserPointer(ClothId id, void* user) {
    (void)core_->clothDesc(id);
    setUser(cloth_users_, id, user);
}
void BulletWorld::setUserPointer(PaperId id, void* user) {
    (void)core_->paperDesc(id);
    setUser(paper_users_, id, user);
}
void* BulletWorld::userPointer(StringId id) const {
    (void)core_->desc(id);
    return user(string_users_, id);
}
void* BulletWorld::userPointer(ClothId id) const {
    (void)core_->clothDesc(id);
    return user(cloth_users_, id);
}
void* BulletWorld::userPointer(PaperId id) const {
    (void)core_->paperDesc(id);
    return user(paper_users_, id);
}

}  // namespace tearables
