// The interactive viewer: one GLFW window with a legacy (compatibility) OpenGL context, the
// scene drawn by the renderer's code (render::drawFrame), Dear ImGui's panels on top
// (Debian's libimgui-dev, GLFW and OpenGL 2 backends), and the mouse and keyboard.
//
// Dragging follows Bullet's example browser: a rigid body is held at the picked point by a
// btPoint2PointConstraint whose pivot follows the cursor, with a clamped impulse. A rope
// particle, cloth vertex or sheet vertex is glued to the "hand", a body without contacts
// or gravity, held the same way: the glue is the plugin's two-way coupling, so the rope's
// tension is what the constraint pulls with (up to the clamp) and it tears past its
// rupture load. (A world pin moved toward the cursor would not do: pins win over the
// strain limit, and a rope between two pins pulled apart stretches without tension.)
// The cursor moves on the plane through the picked point facing the camera.
#include "viewer/viewer.hpp"

#include "render/overlay.hpp"
#include "render/renderer.hpp"
#include "render/scene_painter.hpp"
#include "tearables/bullet_core.hpp"
#include "tearables/colormap.hpp"
#include "tearables/queries.hpp"
#include "viewer/recording.hpp"
#include "viewer/script.hpp"

#include <GLFW/glfw3.h>
#include <btBulletDynamicsCommon.h>
#include <imgui.h>
#include <backends/imgui_impl_glfw.h>
#include <backends/imgui_impl_opengl2.h>

#include <algorithm>
#include <cfloat>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <deque>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>

namespace tearables::viewer {

namespace {

using render::View;

/// Bullet's closest hit among rigid bodies only: ropes are picked through
/// tearables::rayTest (their collision objects, BulletWorld::setRopesRayTestable, are
/// skipped).
struct ClosestBodyHit : btCollisionWorld::ClosestRayResultCallback {
    using ClosestRayResultCallback::ClosestRayResultCallback;
    bool needsCollision(btBroadphaseProxy* proxy) const override {
        return btRigidBody::upcast(static_cast<const btCollisionObject*>(proxy->m_clientObject)) &&
               ClosestRayResultCallback::needsCollision(proxy);
    }
};

/// An orbiting camera: the eye on a sphere around `target`.
struct OrbitCamera {
    Vec3 target = Vec3::Zero();
    double yaw = 0.0;       ///< about +y, rad; 0 looks along -z
    double pitch = 0.3;     ///< above the horizon, rad
    double distance = 3.0;  ///< m
    double fov = 40.0;      ///< degrees

    View view() const {
        View v;
        v.target = target;
        v.eye = target + distance * Vec3(std::cos(pitch) * std::sin(yaw), std::sin(pitch), std::cos(pitch) * std::cos(yaw));
        v.fov = fov;
        return v;
    }
    static OrbitCamera from(const View& v) {
        OrbitCamera c;
        const Vec3 d = v.eye - v.target;
        c.target = v.target;
        c.distance = std::max(d.norm(), 1e-3);
        c.pitch = std::asin(std::clamp(d.y() / c.distance, -1.0, 1.0));
        c.yaw = std::atan2(d.x(), d.z());
        c.fov = v.fov;
        return c;
    }
};

/// The camera's frame as the renderer builds it (lookAt): right, up and forward, unit.
void cameraFrame(const View& v, Vec3& right, Vec3& up, Vec3& forward) {
    forward = (v.target - v.eye).normalized();
    Vec3 hint = v.up;
    if (std::abs(forward.dot(hint.normalized())) > 0.999) hint = std::abs(forward.x()) < 0.9 ? Vec3::UnitX() : Vec3::UnitZ();
    right = forward.cross(hint).normalized();
    up = right.cross(forward);
}

/// The ray through pixel (x, y) from the top-left of a w x h picture: unit direction.
Vec3 pixelRay(const View& v, double x, double y, int w, int h) {
    Vec3 right, up, forward;
    cameraFrame(v, right, up, forward);
    const double t = std::tan(v.fov * M_PI / 360.0);
    const double nx = 2.0 * x / w - 1.0, ny = 1.0 - 2.0 * y / h;
    return (forward + nx * t * (static_cast<double>(w) / h) * right + ny * t * up).normalized();
}

/// Where a world point is seen, in pixels from the top-left (nullopt behind the eye).
std::optional<std::array<double, 2>> projectPoint(const View& v, const Vec3& p, int w, int h) {
    Vec3 right, up, forward;
    cameraFrame(v, right, up, forward);
    const Vec3 d = p - v.eye;
    const double depth = d.dot(forward);
    if (!(depth > 0.0)) return std::nullopt;
    const double t = std::tan(v.fov * M_PI / 360.0);
    const double nx = d.dot(right) / (depth * t * (static_cast<double>(w) / h)), ny = d.dot(up) / (depth * t);
    return std::array<double, 2>{(nx + 1.0) * 0.5 * w, (1.0 - ny) * 0.5 * h};
}

/// What the mouse holds.
struct Grab {
    enum class Kind { None, String, Cloth, Paper, Body };
    /// How: a particle or vertex is glued to the hand (a small body without contacts) that
    /// a point constraint pulls (one pinned to a world point is unpinned while held and
    /// pinned again where it is let go); a body is pulled by a point constraint at the
    /// picked point.
    enum class Mode { Hand, Constraint };
    Kind kind = Kind::None;
    Mode mode = Mode::Constraint;
    bool repin = false;        ///< it was pinned to a world point: pin it again on release
    std::size_t index = 0;     ///< the scene's string / cloth / paper index, or the body index
    int particle = -1;         ///< the particle or vertex held
    Vec3 plane_point = Vec3::Zero();  ///< the drag plane's point (faces the camera)
    Vec3 target = Vec3::Zero();       ///< where the cursor is on that plane
    std::unique_ptr<btPoint2PointConstraint> p2p;
};

/// The name of the viewer's hand body (not drawn, not listed).
const char* const kHandName = "viewer-hand";

double largestRuptureTension(const scene::Scene& s) { return render::ruptureTensions(s).second; }

class Viewer {
public:
    explicit Viewer(const ViewerOptions& options) : opt_(options), scene_(options.scene) {}
    int run();

private:
    // --- the simulation ---
    void restart();
    void stepOnce();
    void applyGrab();
    void releaseGrab();
    btRigidBody& hand();
    bool startGrab(double x, double y);
    bool cutAt(double x, double y);
    void dropCrate();
    // --- input (real and scripted) ---
    void onButton(int button, bool press, bool shift);
    void onCursor(double x, double y);
    void onScroll(double dy);
    void onKey(const std::string& key);
    void runScript();
    // --- drawing ---
    void drawScene();
    void drawPanels();
    void drawLivePanel();
    void drawPlaybackPanel();
    void drawCommonPanels();
    void drawColorBar();
    void writeScreenshot(const std::string& path);
    std::string stateJson() const;

    static void buttonCallback(GLFWwindow* w, int button, int action, int mods);
    static void cursorCallback(GLFWwindow* w, double x, double y);
    static void scrollCallback(GLFWwindow* w, double dx, double dy);
    static void keyCallback(GLFWwindow* w, int key, int scancode, int action, int mods);

    ViewerOptions opt_;
    scene::Scene scene_;
    std::unique_ptr<scene::SceneRun> run_;   // live, or
    std::unique_ptr<Recording> rec_;         // playing a recorded run back
    double play_time_ = 0.0;                 // s, in the recording
    double play_speed_ = 1.0;                // recorded seconds per second; negative plays backwards
    std::vector<float> rec_tension_;         // the recording's most loaded segment, per frame, N
    GLFWwindow* window_ = nullptr;
    std::unique_ptr<render::Renderer> renderer_;
    OrbitCamera camera_;
    int fb_w_ = 0, fb_h_ = 0;      // framebuffer, pixels
    int win_w_ = 0, win_h_ = 0;    // window, screen units (cursor coordinates)

    bool paused_ = false;
    bool step_once_ = false;
    double speed_ = 1.0;           // simulated seconds per second
    double accumulator_ = 0.0;     // simulated time owed, s
    bool cut_tool_ = false;
    bool show_help_ = true;
    bool show_panels_ = true;     // the ImGui panels (the colour bar stays)
    render::RopeColors rope_colors_ = render::RopeColors::Load;  // T: twist alone
    bool quit_ = false;

    Grab grab_;
    btRigidBody* hand_ = nullptr;  // the body a held particle is glued to (created at the first grab)
    double max_pull_ = 100.0;      // N, the strongest pull of a held point (slider)
    double cursor_x_ = 0.0, cursor_y_ = 0.0;
    bool orbiting_ = false, panning_ = false;

    double crate_mass_ = 5.0;      // kg
    int crates_ = 0;
    bool wind_on_ = false;
    float wind_speed_ = 8.0f;      // m/s along +x
    bool scene_has_wind_ = false;

    std::deque<Event> events_;          // newest last, at most kMaxEvents
    std::vector<Event> all_events_;     // for --print-state
    std::deque<float> tension_history_; // the most loaded segment's tension per frame, N
    double max_tension_ = 0.0;
    std::string max_tension_where_;
    std::string status_;

    std::vector<ScriptCommand> script_;
    std::size_t script_pc_ = 0;
    long long script_wait_ = 0;
    std::string pending_screenshot_;

    static constexpr float kLeftWidth = 320.0f, kRightWidth = 300.0f;  // the panels' columns, pixels
    static constexpr std::size_t kMaxEvents = 200;
    static constexpr std::size_t kHistory = 600;
};

void Viewer::restart() {
    if (rec_) {
        play_time_ = play_speed_ >= 0.0 ? rec_->startTime() : rec_->endTime();
        return;
    }
    releaseGrab();
    run_ = std::make_unique<scene::SceneRun>(scene_, scene::RunOptions{});
    hand_ = nullptr;
    crates_ = 0;
    events_.clear();
    tension_history_.clear();
    accumulator_ = 0.0;
    run_->setSceneWind(true);
    run_->setExtraWind(wind_on_ ? Vec3(wind_speed_, 0.0, 0.0) : Vec3::Zero());
}

void Viewer::stepOnce() {
    if (rec_) {  // one recorded frame on, in the direction of play
        const std::size_t i = rec_->frameAt(play_time_);
        if (play_speed_ >= 0.0 && i + 1 < rec_->size()) play_time_ = rec_->at(i + 1).time;
        if (play_speed_ < 0.0 && i > 0) play_time_ = rec_->at(i - 1).time;
        return;
    }
    applyGrab();
    run_->advance();
    for (const Event& e : run_->lastEvents()) {
        events_.push_back(e);
        if (events_.size() > kMaxEvents) events_.pop_front();
        if (all_events_.size() < 100000) all_events_.push_back(e);
    }
}

void Viewer::applyGrab() {
    if (grab_.kind == Grab::Kind::None || !run_) return;
    grab_.p2p->setPivotB(toBullet(grab_.target));
}

btRigidBody& Viewer::hand() {
    if (!hand_) {
        scene::Body spec;
        spec.name = kHandName;
        spec.shape.kind = scene::Shape::Kind::Sphere;
        spec.shape.radius = 0.005;
        spec.mass = 1.0;
        hand_ = &run_->addBody(spec);
        // No contacts (the strings' and Bullet's collision both skip it), no gravity.
        hand_->setCollisionFlags(hand_->getCollisionFlags() | btCollisionObject::CF_NO_CONTACT_RESPONSE);
        hand_->setGravity(btVector3(0, 0, 0));
    }
    return *hand_;
}

void Viewer::releaseGrab() {
    if (grab_.kind == Grab::Kind::None || !run_) {
        grab_ = Grab{};
        return;
    }
    World& core = run_->ropes().core();
    if (grab_.mode == Grab::Mode::Hand) {
        try {
            if (grab_.kind == Grab::Kind::String) {
                const StringId id = run_->stringId(grab_.index);
                core.detach(id, grab_.particle);
                if (grab_.repin) core.attachToPoint(id, grab_.particle, (*core.view(id).positions)[static_cast<std::size_t>(grab_.particle)]);
            }
            if (grab_.kind == Grab::Kind::Cloth) {
                const ClothId id = run_->clothId(grab_.index);
                core.detachCloth(id, grab_.particle);
                if (grab_.repin) core.attachClothToPoint(id, grab_.particle, (*core.viewCloth(id).positions)[static_cast<std::size_t>(grab_.particle)]);
            }
            if (grab_.kind == Grab::Kind::Paper) {
                const PaperId id = run_->paperId(grab_.index);
                const auto v = static_cast<std::uint32_t>(grab_.particle);
                core.detachPaper(id, v);
                if (grab_.repin) core.attachPaperToPoint(id, v, (*core.viewPaper(id).positions)[v]);
            }
        } catch (const InvalidInput&) {
        }
    }
    if (grab_.p2p) {
        run_->dynamicsWorld().removeConstraint(grab_.p2p.get());
        btRigidBody& b = grab_.p2p->getRigidBodyA();
        if (&b == hand_) {
            b.setLinearVelocity(btVector3(0, 0, 0));
            b.forceActivationState(DISABLE_SIMULATION);  // parked until the next grab
        } else {
            b.forceActivationState(ACTIVE_TAG);
            b.setDeactivationTime(0);
        }
    }
    grab_ = Grab{};
}

bool Viewer::startGrab(double x, double y) {
    if (!run_) return false;  // playback: the mouse only moves the camera
    const View v = camera_.view();
    const Vec3 dir = pixelRay(v, x, y, win_w_, win_h_);
    const double reach = 1000.0 * std::max(camera_.distance, 1.0);
    const Vec3 from = v.eye, to = v.eye + reach * dir;
    World& core = run_->ropes().core();

    double best = 2.0;  // ray fraction of the nearest pick
    Grab pick;
    if (const auto hit = rayTest(core, from, to)) {
        best = hit->fraction;
        pick.kind = Grab::Kind::String;
        for (std::size_t i = 0; i < scene_.strings.size(); ++i)
            if (run_->stringId(i) == hit->string) pick.index = i;
        pick.particle = hit->along < 0.5 ? hit->segment : hit->segment + 1;
        pick.plane_point = hit->point;
    }
    // Cloth and sheet vertices within a few pixels of the ray.
    const auto offerVertices = [&](const std::vector<Vec3>& xs, Grab::Kind kind, std::size_t index) {
        for (std::size_t k = 0; k < xs.size(); ++k) {
            const Vec3 d = xs[k] - from;
            const double along = d.dot(dir);
            if (!(along > 0.0)) continue;
            const double pixel = 2.0 * along * std::tan(v.fov * M_PI / 360.0) / win_h_;
            if ((d - along * dir).norm() > 8.0 * pixel) continue;
            const double f = along / reach;
            if (f < best) {
                best = f;
                pick = Grab{};
                pick.kind = kind;
                pick.index = index;
                pick.particle = static_cast<int>(k);
                pick.plane_point = xs[k];
            }
        }
    };
    for (std::size_t i = 0; i < scene_.cloths.size(); ++i)
        offerVertices(*core.viewCloth(run_->clothId(i)).positions, Grab::Kind::Cloth, i);
    for (std::size_t i = 0; i < scene_.papers.size(); ++i)
        offerVertices(*core.viewPaper(run_->paperId(i)).positions, Grab::Kind::Paper, i);
    // Rigid bodies (Bullet's ray test); a static one hides what is behind it.
    ClosestBodyHit body_hit(toBullet(from), toBullet(to));
    run_->dynamicsWorld().rayTest(toBullet(from), toBullet(to), body_hit);
    if (body_hit.hasHit() && body_hit.m_closestHitFraction < best) {
        best = body_hit.m_closestHitFraction;
        pick = Grab{};
        for (std::size_t i = 0; i < run_->bodyCount(); ++i)
            if (&run_->body(i) == body_hit.m_collisionObject && run_->body(i).getInvMass() > 0) {
                pick.kind = Grab::Kind::Body;
                pick.index = i;
                pick.plane_point = toCore(body_hit.m_hitPointWorld);
            }
    }
    if (pick.kind == Grab::Kind::None) return false;

    pick.target = pick.plane_point;
    try {
        Vec3 at = pick.plane_point;  // the held particle or vertex
        bool pinned = false;
        switch (pick.kind) {
            case Grab::Kind::String: {
                const StringId id = run_->stringId(pick.index);
                at = (*core.view(id).positions)[static_cast<std::size_t>(pick.particle)];
                pinned = core.pinTarget(id, pick.particle, nullptr);
                if (!pinned && core.isAttached(id, pick.particle)) {
                    status_ = "that particle is glued to a body: drag the body";
                    return true;
                }
                break;
            }
            case Grab::Kind::Cloth: {
                const ClothId id = run_->clothId(pick.index);
                at = (*core.viewCloth(id).positions)[static_cast<std::size_t>(pick.particle)];
                try {
                    core.moveClothPin(id, pick.particle, at);
                    pinned = true;
                } catch (const InvalidInput&) {
                }
                break;
            }
            case Grab::Kind::Paper: {
                const PaperId id = run_->paperId(pick.index);
                at = (*core.viewPaper(id).positions)[static_cast<std::size_t>(pick.particle)];
                try {
                    core.movePaperPin(id, static_cast<std::uint32_t>(pick.particle), at);
                    pinned = true;
                } catch (const InvalidInput&) {
                }
                break;
            }
            default: break;
        }
        btRigidBody* pulled = nullptr;
        btVector3 local(0, 0, 0);
        if (pick.kind == Grab::Kind::Body) {
            pick.mode = Grab::Mode::Constraint;
            pulled = &run_->body(pick.index);
            local = pulled->getCenterOfMassTransform().inverse() * toBullet(pick.plane_point);
        } else {
            if (pinned) {  // held by the hand instead of the pin until let go
                pick.repin = true;
                if (pick.kind == Grab::Kind::String) core.detach(run_->stringId(pick.index), pick.particle);
                if (pick.kind == Grab::Kind::Cloth) core.detachCloth(run_->clothId(pick.index), pick.particle);
                if (pick.kind == Grab::Kind::Paper) core.detachPaper(run_->paperId(pick.index), static_cast<std::uint32_t>(pick.particle));
            }
            // The hand: moved to the particle, at rest, then the particle is glued to it.
            pick.mode = Grab::Mode::Hand;
            pulled = &hand();
            pulled->forceActivationState(DISABLE_DEACTIVATION);
            btTransform xf = btTransform::getIdentity();
            xf.setOrigin(toBullet(at));
            pulled->setWorldTransform(xf);
            pulled->setInterpolationWorldTransform(xf);
            pulled->setLinearVelocity(btVector3(0, 0, 0));
            pulled->setAngularVelocity(btVector3(0, 0, 0));
            // Heavy enough that the constraint's correction (tau d / dt^2 times the mass, for
            // the cursor d away) reaches the largest pull when the cursor is a tenth of the
            // scene away; at least as heavy as what it holds.
            const render::Bounds bounds = render::sceneBounds(scene_);
            const double full_pull_at = 0.1 * std::max((bounds.hi - bounds.lo).norm(), 0.5);
            double mass = max_pull_ * scene_.dt * scene_.dt / (0.3 * full_pull_at), held = 0.0;
            if (pick.kind == Grab::Kind::String)
                for (double m : *core.view(run_->stringId(pick.index)).masses) held += m;
            if (pick.kind == Grab::Kind::Cloth)
                for (double m : *core.viewCloth(run_->clothId(pick.index)).masses) held += m;
            if (pick.kind == Grab::Kind::Paper)
                for (double m : *core.viewPaper(run_->paperId(pick.index)).masses) held += m;
            mass = std::max({mass, held, 1e-3});
            btVector3 inertia(0, 0, 0);
            pulled->getCollisionShape()->calculateLocalInertia(static_cast<btScalar>(mass), inertia);
            pulled->setMassProps(static_cast<btScalar>(mass), inertia);
            pulled->setGravity(btVector3(0, 0, 0));
            if (pick.kind == Grab::Kind::String) run_->ropes().attach(run_->stringId(pick.index), pick.particle, *pulled, btVector3(0, 0, 0));
            if (pick.kind == Grab::Kind::Cloth) run_->ropes().attachCloth(run_->clothId(pick.index), pick.particle, *pulled, btVector3(0, 0, 0));
            if (pick.kind == Grab::Kind::Paper)
                run_->ropes().attachPaper(run_->paperId(pick.index), static_cast<std::uint32_t>(pick.particle), *pulled, btVector3(0, 0, 0));
        }
        if (pulled) {
            pulled->setActivationState(DISABLE_DEACTIVATION);
            pick.p2p = std::make_unique<btPoint2PointConstraint>(*pulled, local);
            // As Bullet's example browser, with the impulse clamped: the pull is at most
            // max_pull_ newtons (the slider), enough by default to tear the scene's ropes.
            pick.p2p->m_setting.m_impulseClamp = static_cast<btScalar>(max_pull_ * scene_.dt);
            pick.p2p->m_setting.m_tau = static_cast<btScalar>(0.3);
            pick.p2p->setPivotB(toBullet(pick.target));
            run_->dynamicsWorld().addConstraint(pick.p2p.get(), true);
        }
    } catch (const InvalidInput& e) {
        status_ = std::string("cannot hold that: ") + e.what();
        return true;
    }
    grab_ = std::move(pick);
    status_.clear();
    return true;
}

bool Viewer::cutAt(double x, double y) {
    if (!run_) return false;
    const View v = camera_.view();
    const Vec3 dir = pixelRay(v, x, y, win_w_, win_h_);
    const Vec3 to = v.eye + 1000.0 * std::max(camera_.distance, 1.0) * dir;
    World& core = run_->ropes().core();
    const auto hit = rayTest(core, v.eye, to);
    if (!hit) {
        status_ = "cut: no rope there";
        return false;
    }
    core.cutSegment(hit->string, hit->segment);
    status_ = "cut " + core.desc(hit->string).name + " at segment " + std::to_string(hit->segment);
    return true;
}

void Viewer::dropCrate() {
    if (!run_) return;
    const render::Bounds b = render::sceneBounds(scene_);
    const double size = std::max((b.hi - b.lo).norm(), 0.5);
    scene::Body crate;
    crate.name = "crate-" + std::to_string(++crates_);
    const double h = std::clamp(0.05 * size, 0.03, 0.5);
    crate.shape.kind = scene::Shape::Kind::Box;
    crate.shape.half_extents = Vec3::Constant(h);
    crate.mass = crate_mass_;
    crate.friction = 0.8;
    // Above the middle of the scene, over the highest thing.
    crate.position = Vec3(0.5 * (b.lo.x() + b.hi.x()), b.hi.y() + 2.0 * h, 0.5 * (b.lo.z() + b.hi.z()));
    run_->addBody(crate);
    status_ = "dropped " + crate.name;
}

void Viewer::onButton(int button, bool press, bool shift) {
    if (button == 0) {
        if (press) {
            if (cut_tool_ || shift) {
                cutAt(cursor_x_, cursor_y_);
                return;
            }
            if (!startGrab(cursor_x_, cursor_y_)) orbiting_ = true;
            else if (grab_.kind != Grab::Kind::None) onCursor(cursor_x_, cursor_y_);
        } else {
            orbiting_ = false;
            releaseGrab();
        }
    } else {
        panning_ = press;
    }
}

void Viewer::onCursor(double x, double y) {
    const double dx = x - cursor_x_, dy = y - cursor_y_;
    cursor_x_ = x;
    cursor_y_ = y;
    if (grab_.kind != Grab::Kind::None) {
        // The cursor's ray on the plane through the held point facing the camera.
        const View v = camera_.view();
        const Vec3 dir = pixelRay(v, x, y, win_w_, win_h_);
        const Vec3 n = (v.target - v.eye).normalized();
        const double denom = dir.dot(n);
        if (std::abs(denom) > 1e-9) grab_.target = v.eye + dir * ((grab_.plane_point - v.eye).dot(n) / denom);
    } else if (orbiting_) {
        camera_.yaw -= 0.006 * dx;
        camera_.pitch = std::clamp(camera_.pitch + 0.006 * dy, -1.5, 1.5);
    } else if (panning_) {
        const View v = camera_.view();
        Vec3 right, up, forward;
        cameraFrame(v, right, up, forward);
        const double pixel = 2.0 * camera_.distance * std::tan(camera_.fov * M_PI / 360.0) / win_h_;
        camera_.target += pixel * (-dx * right + dy * up);
    }
}

void Viewer::onScroll(double dy) { camera_.distance = std::clamp(camera_.distance * std::pow(0.88, dy), 1e-3, 1e5); }

void Viewer::onKey(const std::string& key) {
    if (key == "space") paused_ = !paused_;
    else if (key == "n") {
        paused_ = true;
        step_once_ = true;
    } else if (key == "r") restart();
    else if (key == "s") speed_ = speed_ < 1.0 ? 1.0 : 0.25;
    else if (key == "plus") speed_ = std::min(speed_ * 2.0, 16.0);
    else if (key == "minus") speed_ = std::max(speed_ / 2.0, 1.0 / 64.0);
    else if (key == "c") cut_tool_ = true;
    else if (key == "g") cut_tool_ = false;
    else if (key == "f") camera_ = OrbitCamera::from(render::fitCamera(scene_, static_cast<double>(win_w_) / win_h_));
    else if (key == "h") show_help_ = !show_help_;
    else if (key == "p") show_panels_ = !show_panels_;
    else if (key == "t") rope_colors_ = rope_colors_ == render::RopeColors::Twist ? render::RopeColors::Load : render::RopeColors::Twist;
    else if (key == "left" || key == "right") {
        paused_ = true;
        const double keep = play_speed_;
        if (rec_) play_speed_ = key == "left" ? -std::abs(play_speed_) : std::abs(play_speed_);
        if (rec_ || key == "right") stepOnce();
        play_speed_ = keep;
    } else if (key == "w" && run_) {
        wind_on_ = !wind_on_;
        run_->setExtraWind(wind_on_ ? Vec3(wind_speed_, 0.0, 0.0) : Vec3::Zero());
    } else if (key == "b") dropCrate();
    else if (key == "backspace" && rec_) play_speed_ = -play_speed_;
    else if (key == "escape" || key == "q") quit_ = true;
}

void Viewer::runScript() {
    if (script_wait_ > 0) {
        --script_wait_;
        return;
    }
    while (script_pc_ < script_.size() && script_wait_ == 0 && pending_screenshot_.empty() && !quit_) {
        const ScriptCommand& c = script_[script_pc_++];
        switch (c.kind) {
            case ScriptCommand::Kind::Frames: script_wait_ = c.count; break;
            case ScriptCommand::Kind::Step:
                for (long long k = 0; k < c.count; ++k) stepOnce();
                break;
            case ScriptCommand::Kind::Move: onCursor(c.x, c.y); break;
            case ScriptCommand::Kind::MoveWorld:
                if (const auto p = projectPoint(camera_.view(), c.point, win_w_, win_h_)) onCursor((*p)[0], (*p)[1]);
                break;
            case ScriptCommand::Kind::Press: onButton(c.button, true, false); break;
            case ScriptCommand::Kind::Release: onButton(c.button, false, false); break;
            case ScriptCommand::Kind::Key: onKey(c.key); break;
            case ScriptCommand::Kind::Screenshot: pending_screenshot_ = c.path; break;
            case ScriptCommand::Kind::Quit: quit_ = true; break;
        }
    }
}

void Viewer::drawScene() {
    renderer_->resize(std::max(fb_w_, 16), std::max(fb_h_, 16));
    scene::FrameState frame = rec_ ? rec_->state(rec_->frameAt(play_time_)) : run_->frame();
    frame.bodies.erase(std::remove_if(frame.bodies.begin(), frame.bodies.end(), [](const scene::FrameBody& b) { return b.name == kHandName; }),
                       frame.bodies.end());
    if (!opt_.follow.empty())
        if (const auto p = render::followPoint(frame, opt_.follow)) camera_.target = *p;
    render::drawFrame(*renderer_, scene_, frame, camera_.view(), rope_colors_);
    // The held point and the cursor, joined by the "spring".
    if (grab_.kind != Grab::Kind::None && run_) {
        World& core = run_->ropes().core();
        Vec3 held = grab_.target;
        if (grab_.kind == Grab::Kind::String) held = (*core.view(run_->stringId(grab_.index)).positions)[static_cast<std::size_t>(grab_.particle)];
        if (grab_.kind == Grab::Kind::Cloth) held = (*core.viewCloth(run_->clothId(grab_.index)).positions)[static_cast<std::size_t>(grab_.particle)];
        if (grab_.kind == Grab::Kind::Paper) held = (*core.viewPaper(run_->paperId(grab_.index)).positions)[static_cast<std::size_t>(grab_.particle)];
        if (grab_.kind == Grab::Kind::Body)
            held = toCore(grab_.p2p->getRigidBodyA().getCenterOfMassTransform() * grab_.p2p->getPivotInA());
        renderer_->drawLines({{held, grab_.target}}, {0.1f, 0.6f, 0.2f}, 2.0f);
    }
    // The most loaded segment now.
    max_tension_ = 0.0;
    max_tension_where_.clear();
    for (const scene::FrameString& s : frame.strings)
        for (std::size_t j = 0; j < s.view.segmentCount(); ++j)
            if (!(*s.view.broken)[j] && (*s.view.tension)[j] > max_tension_) {
                max_tension_ = (*s.view.tension)[j];
                max_tension_where_ = s.name + " [" + std::to_string(j) + "]";
            }
}

/// The colour bars (render/overlay.hpp, colorBars: the headless frames draw the same
/// layout): tension of strings and damage of sheets, bottom (0) to top (1), at the window's
/// right edge.
void Viewer::drawColorBar() {
    ImDrawList* dl = ImGui::GetBackgroundDrawList();
    for (const render::ColorBar& bar : render::colorBars(scene_, win_w_, win_h_, 1.0f, rope_colors_)) {
        for (int k = 0; k < render::ColorBar::kBands; ++k) {
            const auto [top, bottom] = bar.bandRows(k);
            const Rgb c = render::ColorBar::bandColor(k);
            dl->AddRectFilled(ImVec2(bar.x0, top), ImVec2(bar.x1, bottom), ImGui::ColorConvertFloat4ToU32(ImVec4(c.r, c.g, c.b, 1.0f)));
        }
        dl->AddRect(ImVec2(bar.x0 - 1, bar.y0 - 1), ImVec2(bar.x1 + 1, bar.y1 + 1), IM_COL32(60, 60, 60, 255));
        for (const render::TextPlacement& t : bar.labels) {
            const ImVec2 size = ImGui::CalcTextSize(t.text.c_str());
            dl->AddText(ImVec2(t.right - size.x, t.middle - 0.5f * size.y), IM_COL32(30, 30, 30, 255), t.text.c_str());
        }
    }
}

void Viewer::drawPanels() {
    drawColorBar();
    if (!show_panels_) return;
    // The layout leaves the middle to the scene: the controls and the help on the left,
    // the events and the plot on the right, left of the colour bar's labels.
    ImGui::SetNextWindowPos(ImVec2(10, 10), ImGuiCond_Once);
    ImGui::SetNextWindowSize(ImVec2(kLeftWidth, 0), ImGuiCond_Once);
    ImGui::Begin("tearables", nullptr, ImGuiWindowFlags_AlwaysAutoResize);
    ImGui::Text("%s", opt_.scene_arg.c_str());
    if (rec_) drawPlaybackPanel();
    else drawLivePanel();
    ImGui::End();
    drawCommonPanels();
}

void Viewer::drawPlaybackPanel() {
    const std::size_t i = rec_->frameAt(play_time_);
    ImGui::Text("playback: t = %.3f s, step %lld (frame %zu of %zu)", play_time_, rec_->at(i).step, i + 1, rec_->size());
    float t = static_cast<float>(play_time_);
    if (ImGui::SliderFloat("time", &t, static_cast<float>(rec_->startTime()), static_cast<float>(rec_->endTime()), "%.3f s"))
        play_time_ = t;
    if (ImGui::Button(paused_ ? "Play" : "Pause")) paused_ = !paused_;
    ImGui::SameLine();
    if (ImGui::Button("<")) onKey("left");
    ImGui::SameLine();
    if (ImGui::Button(">")) onKey("right");
    ImGui::SameLine();
    if (ImGui::Button("Start")) play_time_ = rec_->startTime();
    ImGui::SameLine();
    if (ImGui::Button("End")) play_time_ = rec_->endTime();
    float speed = static_cast<float>(play_speed_);
    if (ImGui::SliderFloat("speed", &speed, -8.0f, 8.0f, "%.2fx")) play_speed_ = speed;
    ImGui::SameLine();
    if (ImGui::Button("reverse")) play_speed_ = -play_speed_;
    ImGui::Text("most loaded: %.4g N %s", max_tension_, max_tension_where_.c_str());
    ImGui::Checkbox("help (H)", &show_help_);
    bool twist = rope_colors_ == render::RopeColors::Twist;
    if (ImGui::Checkbox("colour by twist (T)", &twist)) rope_colors_ = twist ? render::RopeColors::Twist : render::RopeColors::Load;
}

void Viewer::drawLivePanel() {
    ImGui::Text("t = %.3f s, step %lld%s", run_->time(), run_->step(), run_->step() > run_->steps() ? " (past the scene's end)" : "");
    if (ImGui::Button(paused_ ? "Play" : "Pause")) paused_ = !paused_;
    ImGui::SameLine();
    if (ImGui::Button("Step")) onKey("n");
    ImGui::SameLine();
    if (ImGui::Button("Restart")) restart();
    float speed = static_cast<float>(speed_);
    if (ImGui::SliderFloat("speed", &speed, 1.0f / 64.0f, 16.0f, "%.3gx", ImGuiSliderFlags_Logarithmic)) speed_ = speed;
    bool slow = speed_ < 1.0;
    if (ImGui::Checkbox("slow motion (S)", &slow)) speed_ = slow ? 0.25 : 1.0;
    ImGui::Separator();
    int tool = cut_tool_ ? 1 : 0;
    ImGui::RadioButton("drag (G)", &tool, 0);
    ImGui::SameLine();
    ImGui::RadioButton("cut (C)", &tool, 1);
    cut_tool_ = tool == 1;
    float pull = static_cast<float>(max_pull_);
    if (ImGui::SliderFloat("max pull N", &pull, 0.1f, 1e5f, "%.4g", ImGuiSliderFlags_Logarithmic)) max_pull_ = pull;
    float mass = static_cast<float>(crate_mass_);
    if (ImGui::SliderFloat("crate kg", &mass, 0.1f, 200.0f, "%.3g", ImGuiSliderFlags_Logarithmic)) crate_mass_ = mass;
    if (ImGui::Button("Drop a crate (B)")) dropCrate();
    if (scene_has_wind_) {
        bool on = run_->sceneWind();
        if (ImGui::Checkbox("scene's wind", &on)) run_->setSceneWind(on);
    }
    bool wind = wind_on_;
    const bool wind_changed = ImGui::Checkbox("wind (W)", &wind);
    ImGui::SameLine();
    const bool speed_changed = ImGui::SliderFloat("m/s", &wind_speed_, 0.0f, 40.0f, "%.1f");
    if (wind_changed || speed_changed) {
        wind_on_ = wind;
        run_->setExtraWind(wind_on_ ? Vec3(wind_speed_, 0.0, 0.0) : Vec3::Zero());
    }
    ImGui::Separator();
    ImGui::Text("most loaded: %.4g N %s", max_tension_, max_tension_where_.c_str());
    if (!status_.empty()) ImGui::TextWrapped("%s", status_.c_str());
    ImGui::Checkbox("help (H)", &show_help_);
    bool twist = rope_colors_ == render::RopeColors::Twist;
    if (ImGui::Checkbox("colour by twist (T)", &twist)) rope_colors_ = twist ? render::RopeColors::Twist : render::RopeColors::Load;
}

void Viewer::drawCommonPanels() {
    const float w = static_cast<float>(win_w_), h = static_cast<float>(win_h_);
    const float right_x = w - 110.0f - kRightWidth;
    ImGui::SetNextWindowPos(ImVec2(right_x, 10), ImGuiCond_Once);
    ImGui::SetNextWindowSize(ImVec2(kRightWidth, 0.5f * h - 15.0f), ImGuiCond_Once);
    ImGui::Begin("events");
    if (rec_)
        for (auto it = rec_->events().rbegin(); it != rec_->events().rend(); ++it)
            if (it->time <= play_time_ + 1e-9) ImGui::Text("%8.3f s  %s", it->time, it->text.c_str());
    for (auto it = events_.rbegin(); it != events_.rend(); ++it) {
        const Event& e = *it;
        if (e.segment >= 0)
            ImGui::Text("%7.3f s %s %s [%d] (%s)", e.time, toString(e.type), e.object.c_str(), e.segment, toString(e.cause));
        else
            ImGui::Text("%7.3f s %s %s particle %d (%s)", e.time, toString(e.type), e.object.c_str(), e.particle, toString(e.cause));
    }
    ImGui::End();

    ImGui::SetNextWindowPos(ImVec2(right_x, 0.5f * h + 5.0f), ImGuiCond_Once);
    ImGui::SetNextWindowSize(ImVec2(kRightWidth, std::min(200.0f, 0.5f * h - 15.0f)), ImGuiCond_Once);
    ImGui::Begin("most loaded segment");
    std::vector<float> values(tension_history_.begin(), tension_history_.end());
    if (rec_) values = rec_tension_;  // the whole recording
    const double rupture = largestRuptureTension(scene_);
    char overlay[64];
    std::snprintf(overlay, sizeof overlay, "%.4g N (rupture %.4g N)", max_tension_, rupture);
    // Scaled to what it shows (the rupture tension is in the overlay).
    float top = 1e-3f;
    for (float v : values) top = std::max(top, 1.1f * v);
    if (values.empty()) values.push_back(0.0f);
    ImGui::PlotLines("##tension", values.data(), static_cast<int>(values.size()), 0, overlay, 0.0f, top,
                     ImGui::GetContentRegionAvail());
    ImGui::End();

    if (show_help_) {
        // Under the controls.
        ImGui::SetNextWindowPos(ImVec2(10, std::min(330.0f, 0.5f * h)), ImGuiCond_Once);
        ImGui::SetNextWindowSize(ImVec2(kLeftWidth, 0), ImGuiCond_Once);
        ImGui::Begin("help", &show_help_);
        if (!opt_.description.empty()) ImGui::TextWrapped("%s", opt_.description.c_str());
        if (rec_) ImGui::TextWrapped("playing back %s: Space play/pause, Left/Right one frame, Backspace reverse, R the start", opt_.trace_dir.c_str());
        ImGui::Separator();
        ImGui::TextWrapped(
            "mouse: left-drag on a rope, cloth, sheet or body holds it (a point constraint pulls it toward "
            "the cursor: pull a rope hard and it tears; a pinned point is pinned again where you let go); "
            "left-drag elsewhere orbits; right-drag pans; "
            "wheel zooms; shift-click (or the cut tool) cuts a rope.\n"
            "keys: Space play/pause, N one step, S slow motion, +/- speed, R restart, C cut tool, G drag tool, "
            "B drop a crate, W wind, F fit the camera, T colour by twist, H this help, P all panels, Q or Esc quit.\n"
            "ropes are coloured by load (tension / rupture tension, or torsion / rupture torsion where larger; "
            "T: twist alone), cloths and paper by damage (the bars at the right).");
        ImGui::End();
    }
}

void Viewer::writeScreenshot(const std::string& path) {
    render::Image image = renderer_->finish();  // the back buffer, panels included
    render::writePng(path, image);
}

std::string Viewer::stateJson() const {
    nlohmann::json j;
    if (rec_) {
        const std::size_t i = rec_->frameAt(play_time_);
        j["time"] = play_time_;
        j["step"] = rec_->at(i).step;
        j["frame"] = i;
        return j.dump();
    }
    j["step"] = run_->step();
    j["time"] = run_->time();
    nlohmann::json strings = nlohmann::json::object();
    const World& core = run_->ropes().core();
    for (std::size_t i = 0; i < scene_.strings.size(); ++i) {
        const StringView v = core.view(run_->stringId(i));
        nlohmann::json broken = nlohmann::json::array();
        for (std::size_t s = 0; s < v.segmentCount(); ++s)
            if ((*v.broken)[s]) broken.push_back(s);
        const Vec3& first = v.positions->front();
        const Vec3& last = v.positions->back();
        strings[scene_.strings[i].desc.name] = {{"broken", broken},
                                                {"segments", v.segmentCount()},
                                                {"ends", {{first.x(), first.y(), first.z()}, {last.x(), last.y(), last.z()}}}};
    }
    j["strings"] = strings;
    nlohmann::json events = nlohmann::json::array();
    for (const Event& e : all_events_)
        events.push_back({{"step", e.step}, {"type", toString(e.type)}, {"cause", toString(e.cause)}, {"object", e.object},
                          {"segment", e.segment}, {"particle", e.particle}});
    j["events"] = events;
    j["bodies"] = run_->bodyCount();
    return j.dump();
}

Viewer* self(GLFWwindow* w) { return static_cast<Viewer*>(glfwGetWindowUserPointer(w)); }

void Viewer::buttonCallback(GLFWwindow* w, int button, int action, int mods) {
    Viewer* v = self(w);
    if (action == GLFW_PRESS && ImGui::GetIO().WantCaptureMouse) return;
    if (button == GLFW_MOUSE_BUTTON_LEFT || button == GLFW_MOUSE_BUTTON_RIGHT || button == GLFW_MOUSE_BUTTON_MIDDLE)
        v->onButton(button == GLFW_MOUSE_BUTTON_LEFT ? 0 : 1, action == GLFW_PRESS, (mods & GLFW_MOD_SHIFT) != 0);
}
void Viewer::cursorCallback(GLFWwindow* w, double x, double y) { self(w)->onCursor(x, y); }
void Viewer::scrollCallback(GLFWwindow* w, double, double dy) {
    if (!ImGui::GetIO().WantCaptureMouse) self(w)->onScroll(dy);
}
void Viewer::keyCallback(GLFWwindow* w, int key, int, int action, int) {
    if (action != GLFW_PRESS || ImGui::GetIO().WantCaptureKeyboard) return;
    static const std::map<int, std::string> names = {
        {GLFW_KEY_SPACE, "space"}, {GLFW_KEY_N, "n"}, {GLFW_KEY_R, "r"}, {GLFW_KEY_S, "s"},
        {GLFW_KEY_C, "c"},         {GLFW_KEY_G, "g"}, {GLFW_KEY_F, "f"}, {GLFW_KEY_H, "h"}, {GLFW_KEY_P, "p"}, {GLFW_KEY_T, "t"},
        {GLFW_KEY_W, "w"},         {GLFW_KEY_B, "b"}, {GLFW_KEY_EQUAL, "plus"}, {GLFW_KEY_KP_ADD, "plus"},
        {GLFW_KEY_LEFT, "left"}, {GLFW_KEY_RIGHT, "right"}, {GLFW_KEY_BACKSPACE, "backspace"}, {GLFW_KEY_MINUS, "minus"}, {GLFW_KEY_KP_SUBTRACT, "minus"}, {GLFW_KEY_ESCAPE, "escape"}, {GLFW_KEY_Q, "q"}};
    if (const auto it = names.find(key); it != names.end()) self(w)->onKey(it->second);
}

int Viewer::run() {
    // Bad scripts and recordings fail before a window opens.
    if (!opt_.script.empty()) script_ = loadScript(opt_.script);
    if (!opt_.trace_dir.empty()) {
        rec_ = std::make_unique<Recording>(scene_, opt_.trace_dir);
        for (std::size_t i = 0; i < rec_->size(); ++i) {
            double m = 0.0;
            for (const RecordedString& str : rec_->at(i).strings)
                for (double t : str.tension) m = std::max(m, t);
            rec_tension_.push_back(static_cast<float>(m));
        }
    }
    paused_ = opt_.paused || !opt_.screenshot.empty();
    show_panels_ = !opt_.hide_panels;
    // By default a pull can tear the strongest rope of the scene (half as much again).
    max_pull_ = std::max(1.5 * largestRuptureTension(scene_), 10.0);
    for (const scene::Driver& d : scene_.drivers) scene_has_wind_ |= d.type == scene::Driver::Type::Wind;

    glfwSetErrorCallback([](int code, const char* text) { std::fprintf(stderr, "tearables-view: GLFW error %d: %s\n", code, text); });
    if (!glfwInit()) {
        std::fprintf(stderr, "tearables-view: cannot open a window (no display? try xvfb-run)\n");
        return 1;
    }
    // Legacy OpenGL (the renderer's fixed-function drawing); no multisampling under Xvfb.
    glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 2);
    glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 1);
    glfwWindowHint(GLFW_SAMPLES, 4);
    const std::string title = "tearables view " + opt_.scene_arg;
    window_ = glfwCreateWindow(opt_.width, opt_.height, title.c_str(), nullptr, nullptr);
    if (!window_) {
        glfwWindowHint(GLFW_SAMPLES, 0);
        window_ = glfwCreateWindow(opt_.width, opt_.height, title.c_str(), nullptr, nullptr);
    }
    if (!window_) {
        std::fprintf(stderr, "tearables-view: cannot create an OpenGL window\n");
        glfwTerminate();
        return 1;
    }
    glfwMakeContextCurrent(window_);
    glfwSwapInterval(opt_.script.empty() && opt_.screenshot.empty() ? 1 : 0);
    glfwSetWindowUserPointer(window_, this);
    // Ours first: ImGui's backend chains to them.
    glfwSetMouseButtonCallback(window_, buttonCallback);
    glfwSetCursorPosCallback(window_, cursorCallback);
    glfwSetScrollCallback(window_, scrollCallback);
    glfwSetKeyCallback(window_, keyCallback);
    IMGUI_CHECKVERSION();
    ImGui::CreateContext();
    ImGui::GetIO().IniFilename = nullptr;  // no imgui.ini left behind
    ImGui::StyleColorsLight();
    ImGui_ImplGlfw_InitForOpenGL(window_, true);
    ImGui_ImplOpenGL2_Init();

    glfwGetWindowSize(window_, &win_w_, &win_h_);
    glfwGetFramebufferSize(window_, &fb_w_, &fb_h_);
    renderer_ = std::make_unique<render::Renderer>(std::max(fb_w_, 16), std::max(fb_h_, 16), 1);
    camera_ = OrbitCamera::from(render::fitCamera(scene_, static_cast<double>(win_w_) / std::max(win_h_, 1)));
    if (rec_) {
        if (opt_.steps > 0) play_time_ = rec_->at(rec_->frameAt((static_cast<double>(opt_.steps) + 1e-6) * scene_.dt)).time;
        else restart();
    } else {
        restart();
    }
    if (!opt_.screenshot.empty() && !rec_)
        for (long long k = 0; k < opt_.steps; ++k) stepOnce();

    const bool scripted = !script_.empty() || !opt_.screenshot.empty();
    auto last = std::chrono::steady_clock::now();
    int status = 0;
    long long frames = 0;
    while (!glfwWindowShouldClose(window_) && !quit_) {
        glfwPollEvents();
        glfwGetWindowSize(window_, &win_w_, &win_h_);
        glfwGetFramebufferSize(window_, &fb_w_, &fb_h_);
        if (!script_.empty()) runScript();

        // Simulated time owed: wall time (a fixed 1/60 s a frame when scripted, so that a
        // script plays the same every time) times the speed, in whole steps.
        const auto now = std::chrono::steady_clock::now();
        const double wall = scripted ? 1.0 / 60.0 : std::min(std::chrono::duration<double>(now - last).count(), 0.1);
        last = now;
        if (rec_) {
            if (!paused_) {
                play_time_ = std::clamp(play_time_ + wall * play_speed_, rec_->startTime(), rec_->endTime());
                if (play_time_ == (play_speed_ >= 0.0 ? rec_->endTime() : rec_->startTime())) paused_ = true;
            } else if (step_once_) {
                stepOnce();
            }
        } else if (!paused_ && opt_.screenshot.empty()) {
            accumulator_ += wall * speed_;
            int taken = 0;
            while (accumulator_ >= scene_.dt && taken < 50) {
                stepOnce();
                accumulator_ -= scene_.dt;
                ++taken;
            }
            if (taken == 50) accumulator_ = 0.0;  // cannot keep up: slow down rather than stall
        } else if (step_once_) {
            stepOnce();
        }
        step_once_ = false;

        ImGui_ImplOpenGL2_NewFrame();
        ImGui_ImplGlfw_NewFrame();
        if (scripted) {  // the real pointer (wherever Xvfb put it) takes no part: no hover, no tooltips
            ImGuiIO& io = ImGui::GetIO();
            io.MousePos = ImVec2(-FLT_MAX, -FLT_MAX);
            for (bool& down : io.MouseDown) down = false;
        }
        ImGui::NewFrame();
        drawScene();
        tension_history_.push_back(static_cast<float>(max_tension_));
        if (tension_history_.size() > kHistory) tension_history_.pop_front();
        drawPanels();
        ImGui::Render();
        ImGui_ImplOpenGL2_RenderDrawData(ImGui::GetDrawData());
        ++frames;
        try {
            if (!pending_screenshot_.empty() && frames > 1) {
                writeScreenshot(pending_screenshot_);
                pending_screenshot_.clear();
            }
            // The panels settle their layout in the first frames: the screenshot is the third.
            if (!opt_.screenshot.empty() && frames >= 3) {
                writeScreenshot(opt_.screenshot);
                quit_ = true;
            }
        } catch (const std::exception& e) {
            std::fprintf(stderr, "tearables-view: %s\n", e.what());
            status = 1;
            quit_ = true;
        }
        glfwSwapBuffers(window_);
    }
    if (opt_.print_state) std::printf("%s\n", stateJson().c_str());
    releaseGrab();
    run_.reset();
    renderer_.reset();
    ImGui_ImplOpenGL2_Shutdown();
    ImGui_ImplGlfw_Shutdown();
    ImGui::DestroyContext();
    glfwDestroyWindow(window_);
    glfwTerminate();
    return status;
}

}  // namespace

int runViewer(const ViewerOptions& options) {
    Viewer viewer(options);
    return viewer.run();
}

}  // namespace tearables::viewer
