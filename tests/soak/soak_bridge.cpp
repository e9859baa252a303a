// Soak (issue 8): a hanging bridge of ropes under a steady rain of crates for 100000 steps
// (or argv[1]). Crates are spawned every 0.25 s above the bridge and deleted once they fall
// below the ground. Checks, each a failure with a message: no NaN or frozen rope and no
// error caught in a step; the kinetic energy stays bounded (by what the falling crates bring
// in); once every rope is torn, the resident memory (/proc/self/statm) does not grow.
#include "tearables/bullet_core.hpp"

#include <btBulletDynamicsCommon.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <memory>
#include <vector>

namespace {

long residentPages() {
    std::ifstream statm("/proc/self/statm");
    long size = 0, resident = 0;
    statm >> size >> resident;
    return resident;
}

int failures = 0;
void fail(long long step, const char* what) {
    std::fprintf(stderr, "step %lld: %s\n", step, what);
    ++failures;
}

}  // namespace

int main(int argc, char** argv) {
    const long long steps = argc > 1 ? std::atoll(argv[1]) : 100000;
    const double dt = 0.01;
    btDefaultCollisionConfiguration config;
    btCollisionDispatcher dispatcher(&config);
    btDbvtBroadphase broadphase;
    btSequentialImpulseConstraintSolver solver;
    btDiscreteDynamicsWorld world(&dispatcher, &broadphase, &solver, &config);
    world.setGravity(btVector3(0, -9.81f, 0));
    btStaticPlaneShape ground_shape(btVector3(0, 1, 0), 0);
    btRigidBody ground(btRigidBody::btRigidBodyConstructionInfo(0, nullptr, &ground_shape));
    world.addRigidBody(&ground);

    tearables::BulletWorld ropes(world);
    std::vector<tearables::StringId> ids;
    for (int k = 0; k < 5; ++k) {  // the bridge: five ropes side by side, 2 m span, 1.5 m up
        const double z = -0.2 + 0.1 * k;
        auto d = tearables::StringDesc::straight({-1, 1.5, z}, {1, 1.5, z}, 40);
        d.radius = 0.003;
        d.material.tensile.yield = 6e6;
        d.material.tensile.rupture = 1.2e7;
        d.material.variation = 0.05;
        d.seed = 100 + static_cast<std::uint64_t>(k);
        ids.push_back(ropes.addString(d));
        ropes.attach(ids.back(), 0, btVector3(-1, 1.5f, static_cast<float>(z)));
        ropes.attach(ids.back(), -1, btVector3(1, 1.5f, static_cast<float>(z)));
    }

    btBoxShape crate_shape(btVector3(0.08f, 0.08f, 0.08f));
    const btScalar crate_mass = 10.0f;
    btVector3 inertia;
    crate_shape.calculateLocalInertia(crate_mass, inertia);
    std::vector<std::unique_ptr<btRigidBody>> crates;
    const double drop = 1.0;  // m above the bridge
    // What a falling crate can bring in: its fall to the ground from the spawn height,
    // times the crates in the air at once; the ropes' own energy on top of it is bounded
    // by the same (they are pinned and damped by tearing).
    const double crate_energy = crate_mass * 9.81 * (1.5 + drop);
    double max_energy = 0.0;
    unsigned seed = 12345;

    long baseline = -1;
    long long torn_at = -1, spawned = 0;
    long peak_after = 0;
    for (long long step = 1; step <= steps; ++step) {
        if (step % 25 == 1) {  // a crate every 0.25 s, at a seeded place over the bridge
            seed = seed * 1103515245u + 12345u;
            const float x = -0.8f + 1.6f * static_cast<float>((seed >> 8) % 1000) / 1000.0f;
            const float z = -0.25f + 0.5f * static_cast<float>((seed >> 18) % 1000) / 1000.0f;
            auto crate = std::make_unique<btRigidBody>(btRigidBody::btRigidBodyConstructionInfo(crate_mass, nullptr, &crate_shape, inertia));
            crate->setWorldTransform(btTransform(btQuaternion(0.1f * x, 0.2f, 0.0f), btVector3(x, static_cast<float>(1.5 + drop), z)));
            world.addRigidBody(crate.get());
            crates.push_back(std::move(crate));
            ++spawned;
        }
        world.stepSimulation(static_cast<btScalar>(dt), 1, static_cast<btScalar>(dt));
        ropes.clearEvents();
        if (!ropes.lastError().empty()) {
            fail(step, ropes.lastError().c_str());
            break;
        }
        // Crates that came to rest on the ground or left the scene go: removed from the
        // Bullet world (the plugin drops their proxies at the next step), then deleted.
        for (auto it = crates.begin(); it != crates.end();) {
            btRigidBody* c = it->get();
            const btVector3 p = c->getCenterOfMassPosition();
            if (p.y() < 0.2f || std::abs(p.x()) > 5 || std::abs(p.z()) > 5) {
                world.removeRigidBody(c);
                ropes.forgetBody(*c);
                it = crates.erase(it);
            } else {
                ++it;
            }
        }
        double energy = 0.0;
        bool all_torn = true;
        for (auto id : ids) {
            const auto v = ropes.core().view(id);
            if (v.frozen) fail(step, "a rope froze (non-finite state)");
            bool torn = false;
            for (std::size_t p = 0; p < v.particleCount(); ++p) {
                const auto& x = (*v.positions)[p];
                const auto& u = (*v.velocities)[p];
                if (!x.allFinite() || !u.allFinite()) fail(step, "a rope particle is not finite");
                energy += 0.5 * (*v.masses)[p] * u.squaredNorm();
            }
            for (auto b : *v.broken) torn = torn || b;
            all_torn = all_torn && torn;
        }
        for (const auto& c : crates) {
            const btVector3 u = c->getLinearVelocity();
            if (!std::isfinite(u.x()) || !std::isfinite(u.y()) || !std::isfinite(u.z())) fail(step, "a crate is not finite");
            energy += 0.5 * crate_mass * u.length2();
        }
        max_energy = std::max(max_energy, energy);
        if (energy > 2.0 * crate_energy * static_cast<double>(crates.size() + 1)) {
            std::fprintf(stderr, "energy %.3g J with %zu crates\n", energy, crates.size());
            fail(step, "kinetic energy beyond what the crates bring in");
        }
        if (failures > 10) break;
        // Memory: a baseline once every rope is torn and 10000 more steps have passed
        // (allocators and Bullet's pools have reached their working size), then no growth.
        if (all_torn && torn_at < 0) torn_at = step;
        if (torn_at >= 0 && step == torn_at + 10000) baseline = residentPages();
        if (baseline >= 0 && step % 1000 == 0) peak_after = std::max(peak_after, residentPages());
        if (step % 10000 == 0)
            std::printf("step %lld: %zu crates in the air, %lld spawned, energy %.3g J (max %.3g), resident %ld pages%s\n", step,
                        crates.size(), spawned, energy, max_energy, residentPages(), all_torn ? ", every rope torn" : "");
    }
    for (auto& c : crates) world.removeRigidBody(c.get());
    world.removeRigidBody(&ground);

    if (torn_at < 0) {
        std::fprintf(stderr, "the ropes never all tore: the memory check did not run\n");
        if (steps >= 20000) ++failures;
    } else if (baseline >= 0) {
        const long growth = peak_after - baseline;
        std::printf("memory: %ld pages when torn + 10000 steps, peak %ld after (growth %ld pages)\n", baseline, peak_after, growth);
        if (growth > 256) {  // 1 MiB of 4 KiB pages
            std::fprintf(stderr, "resident memory grew by %ld pages after the ropes were torn\n", growth);
            ++failures;
        }
    }
    std::printf("%s: %lld steps, max kinetic energy %.3g J\n", failures ? "FAILED" : "passed", steps, max_energy);
    std::fflush(stdout);
    return failures ? 1 : 0;
}
