// Runs a loaded scene: builds the Bullet world, its bodies and the strings, applies the
// drivers every step, and writes trace.jsonl, events.jsonl and summary.json.
#include "tearables/bullet_core.hpp"
#include "tearables/queries.hpp"
#include "tearables/scene.hpp"

#include <btBulletDynamicsCommon.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <sstream>

namespace tearables::scene {

namespace {

using json = nlohmann::json;

/// The Bullet side of a scene, torn down in the right order.
struct BulletScene {
    btDefaultCollisionConfiguration config;
    btCollisionDispatcher dispatcher{&config};
    btDbvtBroadphase broadphase;
    btSequentialImpulseConstraintSolver solver;
    btDiscreteDynamicsWorld world{&dispatcher, &broadphase, &solver, &config};
    std::vector<std::unique_ptr<btCollisionShape>> shapes;
    std::vector<std::unique_ptr<btRigidBody>> bodies;
    std::vector<Body> specs;                    // same order as bodies
    std::map<std::string, btRigidBody*> by_name;
    std::vector<std::unique_ptr<btTypedConstraint>> joints;  // destroyed before the bodies

    ~BulletScene() {
        for (auto& j : joints) world.removeConstraint(j.get());
        for (auto& b : bodies) world.removeRigidBody(b.get());
    }
};

/// Joint `spec` between bodies already in `bs`: its world pivot and axis in each body's
/// frame where the bodies start (a body's own collisions with the other are off, as
/// Bullet users usually ask with addConstraint(joint, true)).
void addBulletJoint(BulletScene& bs, const Joint& spec) {
    btRigidBody& a = *bs.by_name.at(spec.body);
    btRigidBody* b = spec.other ? bs.by_name.at(*spec.other) : nullptr;
    const btVector3 pivot = toBullet(spec.pivot), axis = toBullet(spec.axis);
    const btTransform ta = a.getWorldTransform();
    const btVector3 pivot_a = ta.invXform(pivot), axis_a = ta.getBasis().transpose() * axis;
    std::unique_ptr<btTypedConstraint> joint;
    if (spec.kind == Joint::Kind::Slider || spec.kind == Joint::Kind::Fixed || spec.kind == Joint::Kind::Spring) {
        // The joint's frame in the world: at the pivot, a slider's or spring's x along its
        // axis (Bullet's slide), a fixed joint's the world's axes; in each body's frame where
        // they start. A slider's or spring's a is the other body (or the world) and its b the
        // body, so that its coordinate is the body's travel from where it starts relative to
        // the other.
        btTransform frame(btQuaternion::getIdentity(), pivot);
        if (spec.kind != Joint::Kind::Fixed) {
            btVector3 y, z;
            btPlaneSpace1(axis, y, z);
            frame.setBasis(btMatrix3x3(axis.x(), y.x(), z.x(), axis.y(), y.y(), z.y(), axis.z(), y.z(), z.z()));
        }
        const btTransform in_a = ta.inverse() * frame;
        const btTransform in_b = b ? b->getWorldTransform().inverse() * frame : frame;  // the world's fixed body sits at the origin
        if (spec.kind == Joint::Kind::Fixed) {
            joint = std::make_unique<btFixedConstraint>(a, b ? *b : btTypedConstraint::getFixedBody(), in_a, in_b);
        } else if (spec.kind == Joint::Kind::Spring) {
            // Free along x only (lower > upper: free), within the limits where given, on a
            // spring at rest where the bodies start (setStiffness limits a spring too stiff for
            // the step, as Bullet does by default).
            auto spring = b ? std::make_unique<btGeneric6DofSpring2Constraint>(*b, a, in_b, in_a)
                            : std::make_unique<btGeneric6DofSpring2Constraint>(a, in_a);
            const btScalar lower = spec.limits ? static_cast<btScalar>((*spec.limits)[0]) : 1;
            const btScalar upper = spec.limits ? static_cast<btScalar>((*spec.limits)[1]) : -1;
            spring->setLinearLowerLimit(btVector3(lower, 0, 0));
            spring->setLinearUpperLimit(btVector3(upper, 0, 0));
            spring->setAngularLowerLimit(btVector3(0, 0, 0));
            spring->setAngularUpperLimit(btVector3(0, 0, 0));
            spring->enableSpring(0, true);
            spring->setStiffness(0, static_cast<btScalar>(spec.stiffness));
            spring->setDamping(0, static_cast<btScalar>(spec.damping));
            spring->setEquilibriumPoint(0, 0);
            joint = std::move(spring);
        } else {
            auto slider = b ? std::make_unique<btSliderConstraint>(*b, a, in_b, in_a, true) : std::make_unique<btSliderConstraint>(a, in_a, true);
            if (spec.limits) {
                slider->setLowerLinLimit(static_cast<btScalar>((*spec.limits)[0]));
                slider->setUpperLinLimit(static_cast<btScalar>((*spec.limits)[1]));
            }
            if (spec.motor) {
                slider->setPoweredLinMotor(true);
                slider->setTargetLinMotorVelocity(static_cast<btScalar>(spec.motor->velocity));
                slider->setMaxLinMotorForce(static_cast<btScalar>(spec.motor->force));
            }
            joint = std::move(slider);
        }
    } else if (spec.kind == Joint::Kind::Ball) {
        joint = b ? std::make_unique<btPoint2PointConstraint>(a, *b, pivot_a, b->getWorldTransform().invXform(pivot))
                  : std::make_unique<btPoint2PointConstraint>(a, pivot_a);
    } else {
        std::unique_ptr<btHingeConstraint> hinge;
        if (b) {
            const btTransform tb = b->getWorldTransform();
            hinge = std::make_unique<btHingeConstraint>(a, *b, pivot_a, tb.invXform(pivot), axis_a, tb.getBasis().transpose() * axis);
        } else {
            hinge = std::make_unique<btHingeConstraint>(a, pivot_a, axis_a);
        }
        if (spec.limits) hinge->setLimit(static_cast<btScalar>((*spec.limits)[0]), static_cast<btScalar>((*spec.limits)[1]));
        if (spec.motor)
            hinge->enableAngularMotor(true, static_cast<btScalar>(spec.motor->velocity), static_cast<btScalar>(spec.motor->impulse));
        joint = std::move(hinge);
    }
    bs.world.addConstraint(joint.get(), true);
    bs.joints.push_back(std::move(joint));
}

std::unique_ptr<btCollisionShape> makeShape(const Shape& s) {
    switch (s.kind) {
        case Shape::Kind::Box: return std::make_unique<btBoxShape>(toBullet(s.half_extents));
        case Shape::Kind::Sphere: return std::make_unique<btSphereShape>(static_cast<btScalar>(s.radius));
        case Shape::Kind::Capsule:
            return std::make_unique<btCapsuleShape>(static_cast<btScalar>(s.radius), static_cast<btScalar>(2.0 * s.half_height));
        case Shape::Kind::Plane:
            return std::make_unique<btStaticPlaneShape>(toBullet(s.plane_normal), static_cast<btScalar>(s.plane_offset));
    }
    throw std::runtime_error("unknown shape");
}

btRigidBody* addBulletBody(BulletScene& bs, const Body& spec) {
    auto shape = makeShape(spec.shape);
    const bool dynamic = spec.mass > 0.0 && !spec.kinematic && spec.shape.kind != Shape::Kind::Plane;
    btVector3 inertia(0, 0, 0);
    if (dynamic) shape->calculateLocalInertia(static_cast<btScalar>(spec.mass), inertia);
    btRigidBody::btRigidBodyConstructionInfo info(dynamic ? static_cast<btScalar>(spec.mass) : 0.0f, nullptr, shape.get(), inertia);
    info.m_startWorldTransform.setOrigin(toBullet(spec.position));
    const Quat& q = spec.orientation;
    info.m_startWorldTransform.setRotation(btQuaternion(static_cast<btScalar>(q.x()), static_cast<btScalar>(q.y()),
                                                        static_cast<btScalar>(q.z()), static_cast<btScalar>(q.w())));
    info.m_friction = static_cast<btScalar>(spec.friction);
    info.m_restitution = static_cast<btScalar>(spec.restitution);
    auto body = std::make_unique<btRigidBody>(info);
    if (spec.kinematic) {
        body->setCollisionFlags(body->getCollisionFlags() | btCollisionObject::CF_KINEMATIC_OBJECT);
        body->setActivationState(DISABLE_DEACTIVATION);
    }
    body->setLinearVelocity(toBullet(spec.linear_velocity));
    body->setAngularVelocity(toBullet(spec.angular_velocity));
    bs.world.addRigidBody(body.get());
    btRigidBody* raw = body.get();
    bs.shapes.push_back(std::move(shape));
    bs.bodies.push_back(std::move(body));
    bs.specs.push_back(spec);
    bs.by_name[spec.name] = raw;
    return raw;
}

/// Kinematic bodies move by their scene velocities (Bullet reads their transform).
void moveKinematic(BulletScene& bs, double h) {
    for (std::size_t i = 0; i < bs.bodies.size(); ++i) {
        const Body& spec = bs.specs[i];
        if (!spec.kinematic) continue;
        btRigidBody* b = bs.bodies[i].get();
        btTransform xf = b->getWorldTransform();
        btTransform next;
        btTransformUtil::integrateTransform(xf, toBullet(spec.linear_velocity), toBullet(spec.angular_velocity),
                                            static_cast<btScalar>(h), next);
        b->setWorldTransform(next);
        b->setInterpolationWorldTransform(next);
        b->setLinearVelocity(toBullet(spec.linear_velocity));
        b->setAngularVelocity(toBullet(spec.angular_velocity));
    }
}

/// FNV-1a over the bytes of the final state.
class Digest {
public:
    void add(const void* data, std::size_t size) {
        const auto* p = static_cast<const unsigned char*>(data);
        for (std::size_t i = 0; i < size; ++i) {
            hash_ ^= p[i];
            hash_ *= 1099511628211ull;
        }
    }
    void add(double v) { add(&v, sizeof v); }
    void add(const Vec3& v) {
        add(v.x());
        add(v.y());
        add(v.z());
    }
    std::string hex() const {
        char buf[17];
        std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(hash_));
        return buf;
    }

private:
    std::uint64_t hash_ = 1469598103934665603ull;
};

json vec(const Vec3& v) { return json::array({v.x(), v.y(), v.z()}); }
json vec(const btVector3& v) { return json::array({v.x(), v.y(), v.z()}); }

json traceFrame(long long step, double t, const Scene& scene, const std::vector<StringId>& ids,
           const std::vector<ClothId>& cloth_ids, const std::vector<PaperId>& paper_ids, const World& core,
           const BulletScene& bs) {
    json f;
    f["step"] = step;
    f["t"] = t;
    json strings = json::object();
    for (std::size_t i = 0; i < ids.size(); ++i) {
        const StringView v = core.view(ids[i]);
        json s;
        json x = json::array(), tension = json::array(), twist = json::array(), rest = json::array(), broken = json::array();
        for (const Vec3& p : *v.positions) x.push_back(vec(p));
        for (std::size_t j = 0; j < v.segmentCount(); ++j) {
            if ((*v.broken)[j]) {
                tension.push_back(nullptr);
                broken.push_back(j);
            } else {
                tension.push_back((*v.tension)[j]);
            }
            twist.push_back((*v.twist)[j]);
            rest.push_back((*v.rest_length)[j]);
        }
        s["x"] = std::move(x);
        s["tension"] = std::move(tension);
        s["twist"] = std::move(twist);
        s["rest_length"] = std::move(rest);
        s["broken"] = std::move(broken);
        // Link (twist + writhe, turns) where the string is twisted: the writhe costs
        // O(segments^2), and an untwisted string's twist is 0.
        if (std::any_of(v.twist->begin(), v.twist->end(), [](double a) { return a != 0.0; })) {
            const tearables::LinkMeasure link = tearables::linkMeasure(core, ids[i]);
            s["total_twist"] = link.twist;
            s["writhe"] = link.writhe;
        }
        strings[scene.strings[i].desc.name] = std::move(s);
    }
    f["strings"] = std::move(strings);
    if (!cloth_ids.empty()) {
        json cloths = json::object();
        for (std::size_t i = 0; i < cloth_ids.size(); ++i) {
            const ClothView v = core.viewCloth(cloth_ids[i]);
            json x = json::array(), tension = json::array(), rest = json::array(), broken = json::array();
            for (const Vec3& p : *v.positions) x.push_back(vec(p));
            for (std::size_t e = 0; e < v.edgeCount(); ++e) {
                if ((*v.broken)[e]) {
                    tension.push_back(nullptr);
                    broken.push_back(e);
                } else {
                    tension.push_back((*v.tension)[e]);
                }
                rest.push_back((*v.rest_length)[e]);
            }
            // Edges: warp (i, j)-(i+1, j) for j-major, i-minor, then weft (i, j)-(i, j+1).
            cloths[scene.cloths[i].desc.name] = {{"resolution", json::array({v.resolution[0], v.resolution[1]})},
                                                 {"x", std::move(x)},
                                                 {"tension", std::move(tension)},
                                                 {"rest_length", std::move(rest)},
                                                 {"broken", std::move(broken)}};
        }
        f["cloths"] = std::move(cloths);
    }
    json papers = json::object();
    for (std::size_t i = 0; i < paper_ids.size(); ++i) {
        const PaperView v = core.viewPaper(paper_ids[i]);
        json x = json::array(), triangles = json::array();
        for (const Vec3& p : *v.positions) x.push_back(vec(p));
        for (const auto& tri : *v.triangles) triangles.push_back(json::array({tri[0], tri[1], tri[2]}));
        long long broken = 0, hinges = 0;
        for (const PaperSpring& sp : *v.springs) {
            broken += sp.broken && sp.kind == PaperSpringKind::Structural;
            hinges += !sp.broken && sp.kind == PaperSpringKind::Hinge;
        }
        papers[scene.papers[i].desc.name] = {{"x", std::move(x)},
                                             {"triangles", std::move(triangles)},
                                             {"broken_springs", broken},
                                             {"hinges", hinges},
                                             {"creases", v.counters.creases},
                                             {"tears", v.counters.tears}};
    }
    if (!paper_ids.empty()) f["papers"] = std::move(papers);
    json bodies = json::object();
    for (std::size_t i = 0; i < bs.bodies.size(); ++i) {
        const btRigidBody* b = bs.bodies[i].get();
        const btTransform& xf = b->getWorldTransform();
        const btQuaternion q = xf.getRotation();
        bodies[bs.specs[i].name] = {{"p", vec(xf.getOrigin())},
                                    {"q", json::array({q.x(), q.y(), q.z(), q.w()})},
                                    {"v", vec(b->getLinearVelocity())}};
    }
    f["bodies"] = std::move(bodies);
    return f;
}

FrameState frameState(long long step, double t, const Scene& scene, const std::vector<StringId>& ids,
                      const std::vector<ClothId>& cloth_ids, const std::vector<PaperId>& paper_ids, const World& core,
                      const BulletScene& bs) {
    FrameState f;
    f.step = step;
    f.time = t;
    for (std::size_t i = 0; i < ids.size(); ++i)
        f.strings.push_back({scene.strings[i].desc.name, core.view(ids[i]), scene.strings[i].desc.material.tensile.rupture,
                             scene.strings[i].desc.material.torsion.rupture});
    for (std::size_t i = 0; i < cloth_ids.size(); ++i)
        f.cloths.push_back({scene.cloths[i].desc.name, core.viewCloth(cloth_ids[i]), scene.cloths[i].desc.material.tensile.rupture});
    for (std::size_t i = 0; i < paper_ids.size(); ++i) f.papers.push_back({scene.papers[i].desc.name, core.viewPaper(paper_ids[i])});
    for (std::size_t i = 0; i < bs.bodies.size(); ++i) {
        const btTransform& xf = bs.bodies[i]->getWorldTransform();
        const btQuaternion q = xf.getRotation();
        f.bodies.push_back({bs.specs[i].name, bs.specs[i].shape, toCore(xf.getOrigin()), Quat(q.w(), q.x(), q.y(), q.z())});
    }
    return f;
}

/// Bullet's closest hit among rigid bodies only: the ropes' own collision objects
/// (BulletWorld::setRopesRayTestable) are left to tearables::rayTest, which gives where
/// along the segment the ray met it.
struct ClosestBodyHit : btCollisionWorld::ClosestRayResultCallback {
    using ClosestRayResultCallback::ClosestRayResultCallback;
    bool needsCollision(btBroadphaseProxy* proxy) const override {
        return btRigidBody::upcast(static_cast<const btCollisionObject*>(proxy->m_clientObject)) &&
               ClosestRayResultCallback::needsCollision(proxy);
    }
};

/// What a shot of a "shoot" driver met.
struct Shot {
    bool hit = false;
    std::string object;        ///< the body or string hit
    Vec3 point = Vec3::Zero(); ///< where, m
    double impulse = 0.0;      ///< the impulse given, N s: the driver's, or less where it was clamped
};

/// One shot: the driver's ray is cast at the rigid bodies (Bullet's ray test) and at the
/// strings (tearables::rayTest); the nearest of the two takes the impulse, along the ray. A
/// dynamic body takes it at the hit point (so a shot off its centre line spins it); a
/// string segment shares it between its two particles by where along it the ray met it,
/// as a force over the coming step. Static and kinematic bodies stop the shot unmoved.
/// Paper sheets and cloths are not hit.
Shot shoot(BulletScene& bs, World& core, const Scene& scene, const std::vector<StringId>& ids, const Driver& d, double dt) {
    const btVector3 from = toBullet(d.ray_from), to = toBullet(d.ray_to);
    bs.world.updateAabbs();
    ClosestBodyHit body_hit(from, to);
    bs.world.rayTest(from, to, body_hit);
    const double body_fraction = body_hit.hasHit() ? static_cast<double>(body_hit.m_closestHitFraction) : 2.0;
    const std::optional<RayHit> string_hit = rayTest(core, d.ray_from, d.ray_to);
    Vec3 impulse = d.impulse * (d.ray_to - d.ray_from).normalized();
    Shot shot;
    shot.impulse = d.impulse;
    if (string_hit && string_hit->fraction <= body_fraction) {
        for (std::size_t i = 0; i < ids.size(); ++i)
            if (ids[i] == string_hit->string) shot.object = scene.strings[i].desc.name;
        // Each particle's share of the impulse changes its velocity by share / mass: no more
        // than kMaxDriverSpeed (the clamp the step would apply anyway, silently).
        const std::vector<double>& masses = *core.view(string_hit->string).masses;
        const double dv = std::max((1.0 - string_hit->along) * d.impulse / masses[string_hit->segment],
                                   string_hit->along * d.impulse / masses[string_hit->segment + 1]);
        if (dv > kMaxDriverSpeed) {
            shot.impulse = d.impulse * kMaxDriverSpeed / dv;
            impulse *= kMaxDriverSpeed / dv;
        }
        core.applyForce(string_hit->string, string_hit->segment, (1.0 - string_hit->along) / dt * impulse);
        core.applyForce(string_hit->string, string_hit->segment + 1, string_hit->along / dt * impulse);
        shot.hit = true;
        shot.point = string_hit->point;
        return shot;
    }
    if (!body_hit.hasHit()) return shot;
    shot.hit = true;
    shot.point = toCore(body_hit.m_hitPointWorld);
    for (std::size_t i = 0; i < bs.bodies.size(); ++i)
        if (bs.bodies[i].get() == body_hit.m_collisionObject) {
            shot.object = bs.specs[i].name;
            btRigidBody* b = bs.bodies[i].get();
            if (b->getInvMass() > 0.0f) {
                const double dv = d.impulse * static_cast<double>(b->getInvMass());  // the body's change of speed
                if (dv > kMaxDriverSpeed) {
                    shot.impulse = d.impulse * kMaxDriverSpeed / dv;
                    impulse *= kMaxDriverSpeed / dv;
                }
                b->activate(true);
                b->applyImpulse(toBullet(impulse), body_hit.m_hitPointWorld - b->getCenterOfMassPosition());
            }
        }
    return shot;
}

json eventJson(const Event& e) {
    json j = {{"step", e.step}, {"t", e.time}, {"type", toString(e.type)}, {"object", e.object}};
    if (e.segment >= 0) j["segment"] = e.segment;
    if (e.particle >= 0) j["particle"] = e.particle;
    j["cause"] = toString(e.cause);
    if (e.type == EventType::Tear || e.type == EventType::Yield) j["stress"] = e.stress;
    // Paper: a crease's compression 1 - l/l0, a hinge's folded ratio l/l0 (dimensionless).
    if (e.type == EventType::Crease) j["compression"] = e.stress;
    if (e.type == EventType::Hinge) j["ratio"] = e.stress;
    if (e.type == EventType::Overlap) j["depth"] = e.depth;
    return j;
}

std::ofstream openOut(const std::filesystem::path& path) {
    std::ofstream out(path);
    if (!out) throw std::runtime_error("cannot write " + path.string());
    return out;
}

/// Quadratic drag of air (1.2 kg/m^3, C_d 1.2) on each intact segment's projected area,
/// from `wind` (m/s) relative to the segment, shared by its two particles.
void blowOnStrings(World& core, const std::vector<StringId>& ids, const Vec3& wind) {
    for (StringId id : ids) {
        const StringView v = core.view(id);
        for (std::size_t j = 0; j < v.segmentCount(); ++j) {
            if ((*v.broken)[j]) continue;
            const Vec3 seg = (*v.positions)[j + 1] - (*v.positions)[j];
            const double len = seg.norm();
            if (len <= 0.0) continue;
            const Vec3 axis = seg / len;
            Vec3 rel = wind - 0.5 * ((*v.velocities)[j] + (*v.velocities)[j + 1]);
            rel -= axis * axis.dot(rel);
            const Vec3 f = 0.5 * 1.2 * 1.2 * (2.0 * v.radius * len) * rel.norm() * rel;
            core.applyForce(id, static_cast<int>(j), 0.5 * f);
            core.applyForce(id, static_cast<int>(j + 1), 0.5 * f);
        }
    }
}

/// The same air on sheets, face by face by its normal (addFaceDrag, tearables/paper.hpp):
/// every live paper's triangles and every cloth's intact cells.
void blowOnSheets(World& core, const std::vector<PaperId>& papers, const std::vector<ClothId>& cloths, const Vec3& wind,
                  std::vector<Vec3>& drag) {
    for (PaperId id : papers) {
        const PaperView v = core.viewPaper(id);
        if (v.frozen) continue;
        drag.assign(v.vertexCount(), Vec3::Zero());
        addFaceDrag(*v.positions, *v.velocities, *v.triangles, wind, 1.2, 1.2, drag);
        for (std::size_t i = 0; i < drag.size(); ++i)
            if (drag[i] != Vec3::Zero()) core.applyPaperForce(id, static_cast<std::uint32_t>(i), drag[i]);
    }
    for (ClothId id : cloths) {
        const ClothView v = core.viewCloth(id);
        if (v.frozen) continue;
        drag.assign(v.vertexCount(), Vec3::Zero());
        addFaceDrag(*v.positions, *v.velocities, clothFaces(v), wind, 1.2, 1.2, drag);
        for (std::size_t i = 0; i < drag.size(); ++i)
            if (drag[i] != Vec3::Zero()) core.applyClothForce(id, static_cast<int>(i), drag[i]);
    }
}

void drawProgress(long long done, long long total) {
    const int width = 40;
    const int filled = total > 0 ? static_cast<int>(width * done / total) : width;
    std::fprintf(stderr, "\r[%s%s] %3lld%% step %lld/%lld", std::string(filled, '#').c_str(),
                 std::string(width - filled, ' ').c_str(), total > 0 ? 100 * done / total : 100, done, total);
    if (done == total) std::fprintf(stderr, "\n");
    std::fflush(stderr);
}

}  // namespace

struct SceneRun::Impl {
    Scene scene;
    RunOptions options;
    long long steps = 0;
    int every = 1;
    double dt = 0.01;
    BulletScene bs;
    std::unique_ptr<BulletWorld> ropes;  // after bs: destroyed before it
    std::vector<StringId> ids;
    std::vector<ClothId> cloth_ids;
    std::vector<PaperId> paper_ids;
    std::map<std::string, ClothId> cloth_by_name;
    std::map<std::string, PaperId> paper_by_name;
    std::map<std::string, StringId> string_ids;
    std::ofstream trace, events;
    bool write = false;
    std::filesystem::path dir;
    std::vector<std::uint8_t> done;
    std::vector<std::size_t> shots_fired;  // shoot drivers: shots taken so far
    std::map<std::string, long long> counts;
    double wall = 0.0, paper_seconds = 0.0;
    IslandTotals islands;
    std::uint64_t wind_state = 0;
    long long steps_taken = 0;
    std::vector<Event> last_events;
    bool scene_wind = true;
    Vec3 extra_wind = Vec3::Zero();
    std::vector<Vec3> sheet_drag;  // wind: per vertex of one sheet, N

    Impl(const Scene& scene_in, const RunOptions& options_in);
    void advance();
    std::string overlapBodyName(const Event& e) const;
    RunResult finish();
};

SceneRun::Impl::Impl(const Scene& scene_in, const RunOptions& options_in)
    : scene(scene_in), options(options_in), steps(options_in.steps.value_or(scene_in.steps)),
      every(options_in.every.value_or(scene_in.output_every)), dt(scene_in.dt) {
    if (steps < 0 || steps > 1'000'000'000) throw InvalidInput("--steps", "must be in [0, 1000000000] (got " + std::to_string(steps) + ")");
    if (every < 1) throw InvalidInput("--every", "must be >= 1");
    checkResources(scene, options.limits);

    for (std::size_t d = 0; d < scene.drivers.size(); ++d) {
        const Driver& drv = scene.drivers[d];
        const std::string path = "drivers[" + std::to_string(d) + "]";
        if (drv.cloth) continue;  // cloth targets are checked when they act
        if (drv.type == Driver::Type::Twist)
            for (const String& s : scene.strings)
                if (s.desc.name == drv.target) {
                    const int n = static_cast<int>(s.desc.points.size());
                    const int end = drv.end == 0 ? 0 : n - 1;
                    const bool pinned = std::any_of(s.attachments.begin(), s.attachments.end(), [&](const Attachment& a) {
                        return a.world && (a.particle + n) % n == end;
                    });
                    if (!pinned)
                        throw InvalidInput(path + ".end", "that end of \"" + s.desc.name +
                                                              "\" is not clamped: attach its particle to a world point");
                }
        if (drv.type == Driver::Type::Move && drv.paper_vertex >= 0)
            for (const Paper& p : scene.papers)
                if (p.desc.name == drv.target)
                    for (const SheetGlue& g : p.glue)
                        if (static_cast<int>(g.vertex) == drv.paper_vertex)
                            throw InvalidInput(path + ".vertex", "is glued to body \"" + g.body + "\" and cannot be moved");
        if (drv.type == Driver::Type::Move)
            for (const String& s : scene.strings)
                if (s.desc.name == drv.target)
                    for (const Attachment& a : s.attachments) {
                        const int n = static_cast<int>(s.desc.points.size());
                        if (a.body && (a.particle + n) % n == (drv.particle + n) % n)
                            throw InvalidInput(path + ".particle", "is glued to body \"" + *a.body + "\" and cannot be moved");
                    }
    }

    // --- build ------------------------------------------------------------------------
    bs.world.setGravity(toBullet(scene.gravity));
    for (const Body& b : scene.bodies) addBulletBody(bs, b);
    for (const Joint& j : scene.joints) addBulletJoint(bs, j);
    ropes = std::make_unique<BulletWorld>(bs.world);
    for (std::size_t i = 0; i < scene.strings.size(); ++i) {
        const String& s = scene.strings[i];
        const std::string path = "strings[" + std::to_string(i) + "]";
        try {
            ids.push_back(ropes->addString(s.desc, s.collision_group, s.collision_mask));
            for (std::size_t k = 0; k < s.attachments.size(); ++k) {
                const Attachment& a = s.attachments[k];
                if (a.world) {
                    ropes->attach(ids.back(), a.particle, toBullet(*a.world));
                } else {
                    // Without local: glued where the particle is, in the body's frame.
                    btRigidBody* body = bs.by_name.at(*a.body);
                    const btVector3 at = toBullet(s.desc.points[static_cast<std::size_t>(a.particle)]);
                    const btVector3 local = a.local ? toBullet(*a.local) : body->getCenterOfMassTransform().inverse() * at;
                    ropes->attach(ids.back(), a.particle, *body, local);
                }
            }
        } catch (const InvalidInput& e) {
            throw InvalidInput(path + "." + e.field(), e.problem());
        }
    }
    for (std::size_t i = 0; i < scene.cloths.size(); ++i) {
        const Cloth& c = scene.cloths[i];
        const std::string path = "cloths[" + std::to_string(i) + "]";
        try {
            cloth_ids.push_back(ropes->addCloth(c.desc, c.collision_group, c.collision_mask));
            for (const SheetGlue& g : c.glue) {
                // Without local: glued where the vertex is, in the body's frame.
                btRigidBody* body = bs.by_name.at(g.body);
                const btVector3 at = toBullet((*ropes->core().viewCloth(cloth_ids.back()).positions)[g.vertex]);
                const btVector3 local = g.local ? toBullet(*g.local) : body->getCenterOfMassTransform().inverse() * at;
                ropes->attachCloth(cloth_ids.back(), static_cast<int>(g.vertex), *body, local);
            }
        } catch (const InvalidInput& e) {
            throw InvalidInput(path + "." + e.field(), e.problem());
        }
    }
    for (std::size_t i = 0; i < scene.papers.size(); ++i) {
        const Paper& p = scene.papers[i];
        const std::string path = "papers[" + std::to_string(i) + "]";
        try {
            paper_ids.push_back(ropes->addPaper(p.desc, p.collision_group, p.collision_mask));
            for (const SheetGlue& g : p.glue) {
                btRigidBody* body = bs.by_name.at(g.body);
                // Default: glued where the vertex is, in the body's frame.
                const btVector3 at = tearables::toBullet((*ropes->core().viewPaper(paper_ids.back()).positions)[g.vertex]);
                const btVector3 local = g.local ? tearables::toBullet(*g.local) : body->getCenterOfMassTransform().inverse() * at;
                ropes->attachPaper(paper_ids.back(), g.vertex, *body, local);
            }
        } catch (const InvalidInput& e) {
            throw InvalidInput(path + "." + e.field(), e.problem());
        }
    }
    for (std::size_t i = 0; i < cloth_ids.size(); ++i) cloth_by_name[scene.cloths[i].desc.name] = cloth_ids[i];
    for (std::size_t i = 0; i < paper_ids.size(); ++i) paper_by_name[scene.papers[i].desc.name] = paper_ids[i];
    for (std::size_t i = 0; i < ids.size(); ++i) string_ids[scene.strings[i].desc.name] = ids[i];

    // --- outputs ----------------------------------------------------------------------
    write = !options.out_dir.empty();
    dir = options.out_dir;
    if (write) {
        std::error_code ec;
        std::filesystem::create_directories(dir, ec);
        if (ec) throw std::runtime_error("cannot create " + dir.string() + ": " + ec.message());
        trace = openOut(dir / "trace.jsonl");
        events = openOut(dir / "events.jsonl");
        trace << traceFrame(0, 0.0, scene, ids, cloth_ids, paper_ids, ropes->core(), bs).dump() << '\n';
    }
    if (options.on_frame) options.on_frame(frameState(0, 0.0, scene, ids, cloth_ids, paper_ids, ropes->core(), bs));

    done.assign(scene.drivers.size(), 0);
    shots_fired.assign(scene.drivers.size(), 0);
    wind_state = scene.seed * 0x9E3779B97F4A7C15ull + 1;
}

void SceneRun::Impl::advance() {
    const long long step = ++steps_taken;

    const double t0 = static_cast<double>(step - 1) * dt;
    World& core = ropes->core();
    for (std::size_t d = 0; d < scene.drivers.size(); ++d) {
        const Driver& drv = scene.drivers[d];
        const bool active = t0 >= drv.from && t0 < drv.until;
        if (drv.cloth) {
            const ClothId id = cloth_by_name.at(drv.target);
            switch (drv.type) {
                case Driver::Type::Force:
                    if (active) core.applyClothForce(id, drv.particle, drv.value);
                    break;
                case Driver::Type::Ramp:
                    if (active) core.applyClothForce(id, drv.particle, drv.value * std::min(drv.rate * (t0 - drv.from), kMaxDriverForce));
                    break;
                case Driver::Type::Move:
                    if (active) {
                        const Vec3 at = (*core.viewCloth(id).positions)[static_cast<std::size_t>(drv.particle)];
                        try {
                            core.moveClothPin(id, drv.particle, at + dt * drv.velocity);
                        } catch (const InvalidInput&) {  // not pinned yet: pinned where it is, then moved
                            const bool glued = std::any_of(scene.cloths.begin(), scene.cloths.end(), [&](const Cloth& c) {
                                return c.desc.name == drv.target &&
                                       std::any_of(c.glue.begin(), c.glue.end(), [&](const SheetGlue& g) {
                                           return static_cast<int>(g.vertex) == drv.particle;
                                       });
                            });
                            if (glued)
                                throw InvalidInput("drivers[" + std::to_string(d) + "].vertex", "is glued to a body and cannot be moved");
                            core.attachClothToPoint(id, drv.particle, at);
                            core.moveClothPin(id, drv.particle, at + dt * drv.velocity);
                        }
                    }
                    break;
                case Driver::Type::Release:
                    if (!done[d] && t0 >= drv.at) {
                        core.detachCloth(id, drv.particle);
                        done[d] = 1;
                    }
                    break;
                default: break;
            }
            continue;
        }
        switch (drv.type) {
            case Driver::Type::Force:
                if (active && drv.paper_vertex >= 0)
                    core.applyPaperForce(paper_by_name.at(drv.target), static_cast<std::uint32_t>(drv.paper_vertex), drv.value);
                else if (active)
                    core.applyForce(string_ids.at(drv.target), drv.particle, drv.value);
                break;
            case Driver::Type::Ramp:
                if (active) core.applyForce(string_ids.at(drv.target), drv.particle, drv.value * std::min(drv.rate * (t0 - drv.from), kMaxDriverForce));
                break;
            case Driver::Type::Move:
                if (active && drv.paper_vertex >= 0) {
                    // A paper vertex: pinned where it is at first, then moved.
                    const PaperId id = paper_by_name.at(drv.target);
                    const auto v = static_cast<std::uint32_t>(drv.paper_vertex);
                    const Vec3 at = (*core.viewPaper(id).positions)[v];
                    try {
                        core.movePaperPin(id, v, at + dt * drv.velocity);
                    } catch (const InvalidInput&) {  // not pinned yet (a glued vertex cannot be moved)
                        core.attachPaperToPoint(id, v, at);
                        core.movePaperPin(id, v, at + dt * drv.velocity);
                    }
                } else if (active) {
                    const StringId id = string_ids.at(drv.target);
                    Vec3 target;
                    if (!core.pinTarget(id, drv.particle, &target)) {
                        if (core.isAttached(id, drv.particle))
                            throw InvalidInput("drivers[" + std::to_string(d) + "].particle", "is glued to a body and cannot be moved");
                        target = (*core.view(id).positions)[core.resolveParticle(id, drv.particle)];
                        core.attachToPoint(id, drv.particle, target);
                    }
                    core.movePin(id, drv.particle, target + dt * drv.velocity);
                }
                break;
            case Driver::Type::Release:
                if (!done[d] && t0 >= drv.at) {
                    core.detach(string_ids.at(drv.target), drv.particle);
                    done[d] = 1;
                }
                break;
            case Driver::Type::Spawn:
                if (!done[d] && t0 >= drv.at) {
                    addBulletBody(bs, *drv.body);
                    done[d] = 1;
                }
                break;
            case Driver::Type::Wind:
                if (active && scene_wind) {
                    // Quadratic drag of air (1.2 kg/m^3, C_d 1.2) on each segment's
                    // projected area, from the wind relative to the segment, with a
                    // seeded random gust factor that changes every 0.1 s.
                    if ((step - 1) % std::max<long long>(1, static_cast<long long>(0.1 / dt)) == 0)
                        wind_state = wind_state * 6364136223846793005ull + 1442695040888963407ull;
                    const double u = static_cast<double>(wind_state >> 11) * (1.0 / 9007199254740992.0);
                    const Vec3 wind = drv.value * (1.0 + drv.gust * (2.0 * u - 1.0));
                    blowOnStrings(core, ids, wind);
                    blowOnSheets(core, paper_ids, cloth_ids, wind, sheet_drag);
                }
                break;
            case Driver::Type::Twist:
                if (active) core.turnEnd(string_ids.at(drv.target), drv.end, drv.rate * dt);
                break;
            case Driver::Type::Shoot:
                // Every shot whose time has come (a step may hold several).
                while (shots_fired[d] < drv.times.size() && t0 >= drv.times[shots_fired[d]] - 1e-9 * dt) {
                    ++shots_fired[d];
                    const Shot shot = shoot(bs, core, scene, ids, drv, dt);
                    ++counts["shot"];
                    if (!write) continue;
                    json e = {{"step", step}, {"t", t0}, {"type", "shot"}, {"hit", shot.hit}};
                    if (shot.hit) {
                        e["object"] = shot.object;
                        e["point"] = vec(shot.point);
                    }
                    e["impulse"] = shot.impulse;
                    if (shot.impulse < drv.impulse) e["clamped_from"] = drv.impulse;  // to kMaxDriverSpeed
                    events << e.dump() << '\n';
                }
                break;
            case Driver::Type::Velocity:
                if (active)
                    for (std::size_t b = 0; b < bs.bodies.size(); ++b)
                        if (bs.specs[b].name == drv.body_name) {
                            // A kinematic body keeps moving at it; a dynamic one is set to it.
                            bs.specs[b].linear_velocity = drv.value;
                            bs.bodies[b]->setLinearVelocity(toBullet(drv.value));
                            bs.bodies[b]->activate();
                        }
                break;
        }
    }
    if (extra_wind.squaredNorm() > 0.0) {
        blowOnStrings(ropes->core(), ids, extra_wind);
        blowOnSheets(ropes->core(), paper_ids, cloth_ids, extra_wind, sheet_drag);
    }
    moveKinematic(bs, dt);

    const auto a = std::chrono::steady_clock::now();
    bs.world.stepSimulation(static_cast<btScalar>(dt), 1, static_cast<btScalar>(dt));
    wall += std::chrono::duration<double>(std::chrono::steady_clock::now() - a).count();
    paper_seconds += ropes->core().lastPaperTimes().total();
    for (const tearables::IslandSummary& island : ropes->core().lastIslands()) {
        ++islands.solves;
        islands.iterations += island.iterations;
        islands.most_iterations = std::max(islands.most_iterations, island.iterations);
        if (!(island.residual < 1.0)) ++islands.unconverged;
    }
    if (!ropes->lastError().empty()) throw std::runtime_error("step " + std::to_string(step) + ": " + ropes->lastError());

    last_events = ropes->core().events();  // one internal step a frame: that step's, one per segment
    for (const Event& e : last_events) {
        ++counts[toString(e.type)];
        if (!write) continue;
        json j = eventJson(e);
        if (e.type == EventType::Overlap) j["body"] = overlapBodyName(e);
        events << j.dump() << '\n';
    }
    ropes->clearEvents();
    const bool frame_step = step % every == 0 || step == steps;
    if (write && frame_step)
        trace << traceFrame(step, static_cast<double>(step) * dt, scene, ids, cloth_ids, paper_ids, ropes->core(), bs).dump() << '\n';
    if (options.on_frame && frame_step) options.on_frame(frameState(step, static_cast<double>(step) * dt, scene, ids, cloth_ids, paper_ids, ropes->core(), bs));
}

/// The scene's name of the body an overlap event names (the plugin's event carries the
/// btRigidBody*).
std::string SceneRun::Impl::overlapBodyName(const Event& e) const {
    for (const BulletEvent& b : ropes->events())
        if (b.type == EventType::Overlap && b.string == e.string && b.rigid == e.rigid)
            for (const auto& [name, body] : bs.by_name)
                if (body == b.body) return name;
    return "";
}

RunResult SceneRun::Impl::finish() {
    // --- summary ----------------------------------------------------------------------
    RunResult result;
    result.steps = steps_taken;
    result.simulated_seconds = static_cast<double>(steps_taken) * dt;
    result.wall_seconds = wall;
    for (const auto& [type, n] : counts) result.event_counts.emplace_back(type, n);
    result.islands = islands;
    // Everything the views show (tensions, twist, plastic lengths; the sheet's springs
    // with their kinds, hinges and broken flags, its masses and counters), so that a run
    // that differs only in damage, twist or tension has another digest.
    Digest digest;
    for (StringId id : ids) {
        const StringView v = ropes->core().view(id);
        for (const Vec3& p : *v.positions) digest.add(p);
        for (const Vec3& p : *v.velocities) digest.add(p);
        for (double l : *v.rest_length) digest.add(l);
        for (double l : *v.max_length) digest.add(l);
        for (double t : *v.tension) digest.add(t);
        for (double t : *v.twist) digest.add(t);
        digest.add(v.broken->data(), v.broken->size());
        digest.add(static_cast<double>(v.frozen));
    }
    for (ClothId id : cloth_ids) {
        const ClothView v = ropes->core().viewCloth(id);
        for (const Vec3& p : *v.positions) digest.add(p);
        for (const Vec3& p : *v.velocities) digest.add(p);
        for (double l : *v.rest_length) digest.add(l);
        for (double l : *v.max_length) digest.add(l);
        for (double t : *v.tension) digest.add(t);
        digest.add(v.broken->data(), v.broken->size());
        digest.add(static_cast<double>(v.frozen));
    }
    for (PaperId id : paper_ids) {
        const PaperView v = ropes->core().viewPaper(id);
        for (const Vec3& p : *v.positions) digest.add(p);
        for (const Vec3& p : *v.velocities) digest.add(p);
        for (double m : *v.masses) digest.add(m);
        for (const auto& tri : *v.triangles) digest.add(tri.data(), sizeof tri);
        for (const PaperSpring& sp : *v.springs) {
            const std::uint32_t names[5] = {sp.a, sp.b, sp.hinge[0], sp.hinge[1],
                                            static_cast<std::uint32_t>(sp.kind) | (sp.broken ? 0x100u : 0u)};
            digest.add(names, sizeof names);
            digest.add(sp.rest);
            digest.add(sp.stiffness);
        }
        for (double t : *v.tension) digest.add(t);
        const double counters[3] = {static_cast<double>(v.counters.creases), static_cast<double>(v.counters.hinges),
                                    static_cast<double>(v.counters.tears)};
        digest.add(counters, sizeof counters);
        digest.add(static_cast<double>(v.frozen));
    }
    for (const auto& b : bs.bodies) {
        const btTransform& xf = b->getWorldTransform();
        digest.add(toCore(xf.getOrigin()));
        const btQuaternion q = xf.getRotation();
        digest.add(Vec3(q.x(), q.y(), q.z()));
        digest.add(static_cast<double>(q.w()));
        digest.add(toCore(b->getLinearVelocity()));
        digest.add(toCore(b->getAngularVelocity()));
    }
    result.digest = digest.hex();

    if (write) {
        const StageTimes& st = ropes->totalStageTimes();
        json stages = {{"predict", st.predict},           {"shape_matching", st.shape_matching},
                       {"twist", st.twist},               {"collision", st.collision},
                       {"strain_limit", st.strain_limit}, {"tension", st.tension},
                       {"material", st.material},         {"velocities", st.velocities},
                       {"paper", paper_seconds},
                       {"rigid_bodies", std::max(0.0, wall - st.total() - paper_seconds)}};
        json ev = json::object();
        for (const auto& [type, n] : counts) ev[type] = n;
        json summary = {{"steps", steps_taken},          {"simulated_seconds", result.simulated_seconds},
                        {"wall_seconds", wall},    {"stage_seconds", stages},
                        {"events", ev},            {"digest", result.digest},
                        {"islands", {{"solves", result.islands.solves},
                                     {"iterations", result.islands.iterations},
                                     {"most_iterations", result.islands.most_iterations},
                                     {"unconverged", result.islands.unconverged}}}};
        std::ofstream out = openOut(dir / "summary.json");
        out << summary.dump(2) << '\n';
        if (!trace || !events || !out) throw std::runtime_error("writing the outputs in " + dir.string() + " failed");
    }
    return result;

}

SceneRun::SceneRun(const Scene& scene, const RunOptions& options) : impl_(std::make_unique<Impl>(scene, options)) {}
SceneRun::~SceneRun() = default;
long long SceneRun::step() const { return impl_->steps_taken; }
long long SceneRun::steps() const { return impl_->steps; }
double SceneRun::time() const { return static_cast<double>(impl_->steps_taken) * impl_->dt; }
void SceneRun::advance() { impl_->advance(); }
RunResult SceneRun::finish() { return impl_->finish(); }
FrameState SceneRun::frame() const {
    const Impl& r = *impl_;
    return frameState(r.steps_taken, time(), r.scene, r.ids, r.cloth_ids, r.paper_ids, r.ropes->core(), r.bs);
}
const std::vector<Event>& SceneRun::lastEvents() const { return impl_->last_events; }
const Scene& SceneRun::scene() const { return impl_->scene; }
BulletWorld& SceneRun::ropes() { return *impl_->ropes; }
btDiscreteDynamicsWorld& SceneRun::dynamicsWorld() { return impl_->bs.world; }
StringId SceneRun::stringId(std::size_t i) const { return impl_->ids.at(i); }
ClothId SceneRun::clothId(std::size_t i) const { return impl_->cloth_ids.at(i); }
PaperId SceneRun::paperId(std::size_t i) const { return impl_->paper_ids.at(i); }
std::size_t SceneRun::bodyCount() const { return impl_->bs.bodies.size(); }
btRigidBody& SceneRun::body(std::size_t i) { return *impl_->bs.bodies.at(i); }
const Body& SceneRun::bodySpec(std::size_t i) const { return impl_->bs.specs.at(i); }
btRigidBody& SceneRun::addBody(const Body& body) {
    if (impl_->bs.by_name.count(body.name)) throw InvalidInput("body.name", "\"" + body.name + "\" is taken by another body");
    return *addBulletBody(impl_->bs, body);
}
void SceneRun::setSceneWind(bool on) { impl_->scene_wind = on; }
bool SceneRun::sceneWind() const { return impl_->scene_wind; }
void SceneRun::setExtraWind(const Vec3& velocity) {
    if (!velocity.allFinite() || velocity.norm() > kMaxDriverSpeed)
        throw InvalidInput("wind", "must be finite and at most " + std::to_string(kMaxDriverSpeed) + " m/s");
    impl_->extra_wind = velocity;
}

RunResult runScene(const Scene& scene, const RunOptions& options) {
    SceneRun run(scene, options);
    const long long steps = run.steps();
    const long long progress_every = std::max<long long>(1, steps / 100);
    for (long long step = 1; step <= steps; ++step) {
        run.advance();
        if (options.progress && (step % progress_every == 0 || step == steps)) drawProgress(step, steps);
    }
    return run.finish();
}

}  // namespace tearables::scene
