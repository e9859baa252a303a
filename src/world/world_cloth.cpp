// World's cloth API: validates the arguments and forwards to the world's ClothSystem
// (src/cloth/system.cpp).
#include "base/validate.hpp"
#include "cloth/cloth_state.hpp"
#include "tearables/world.hpp"

#include <string>

namespace tearables {

namespace {

std::size_t resolveVertex(const detail::ClothState& c, int vertex) {
    return detail::resolveSignedIndex(vertex, c.vertices(), "vertex", "vertex", "cloth", "vertices");
}

}  // namespace

void World::removeCloth(ClothId id) { clothSystem().remove(id); }
std::vector<ClothId> World::cloths() const { return clothSystem().ids(); }
bool World::contains(ClothId id) const { return clothSystem().contains(id); }
const ClothDesc& World::clothDesc(ClothId id) const { return clothSystem().get(id).desc; }

ClothView World::viewCloth(ClothId id) const {
    const detail::ClothState& c = clothSystem().get(id);
    ClothView v;
    v.positions = &c.x;
    v.velocities = &c.v;
    v.masses = &c.mass;
    v.edges = &c.edges;
    v.kinds = &c.kinds;
    v.tension = &c.tension;
    v.rest_length = &c.rest_length;
    v.max_length = &c.max_length;
    v.broken = &c.broken;
    v.resolution = {c.nu, c.nv};
    v.yarn_radius = c.desc.yarn_radius;
    v.tension_residual = c.tension_residual;
    v.tension_iterations = c.tension_iterations;
    v.frozen = c.frozen;
    return v;
}

void World::attachClothToPoint(ClothId id, int vertex, const Vec3& point) {
    detail::ClothState& c = clothSystem().get(id);
    const std::size_t p = resolveVertex(c, vertex);
    detail::requirePosition("point", point);
    c.hold[p].kind = detail::ParticleHold::Kind::Pin;
    c.hold[p].point = point;
    c.hold[p].body = RigidId{};
    c.x[p] = point;
    c.v[p].setZero();
}

void World::attachClothToRigid(ClothId id, int vertex, RigidId body, const Vec3& local_point) {
    detail::ClothState& c = clothSystem().get(id);
    const std::size_t p = resolveVertex(c, vertex);
    const RigidState& b = rigid(body);  // throws for an unknown body
    detail::requirePosition("local", local_point);
    detail::glueVertex(c, p, body, b, local_point);
}

void World::moveClothPin(ClothId id, int vertex, const Vec3& point) {
    detail::ClothState& c = clothSystem().get(id);
    const std::size_t p = resolveVertex(c, vertex);
    if (c.hold[p].kind != detail::ParticleHold::Kind::Pin) throw InvalidInput("vertex", "is not pinned to a world point");
    detail::requirePosition("point", point);
    c.hold[p].point = point;
}

void World::detachCloth(ClothId id, int vertex) {
    detail::ClothState& c = clothSystem().get(id);
    clothSystem().release(id, resolveVertex(c, vertex), EventCause::Request, time(), stepCount(), pendingEvents());
}

void World::applyClothForce(ClothId id, int vertex, const Vec3& force) {
    detail::ClothState& c = clothSystem().get(id);
    const std::size_t p = resolveVertex(c, vertex);
    if (!force.allFinite()) throw InvalidInput("force", "must be finite");
    c.force[p] += force;
}

}  // namespace tearables
