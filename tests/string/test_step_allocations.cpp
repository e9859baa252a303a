// Issue 9: a running step allocates nothing. A separate executable (tearables_alloc_tests),
// because it replaces the global operator new / delete and interposes malloc, calloc and
// realloc (Eigen's dynamic matrices go to malloc directly) to count every heap allocation
// of the process; in the main test binary that would count GoogleTest's and the other
// tests' allocations too.
//
// The counters run only between start() and stop() (all threads: the pool's workers
// allocate through the same functions). With TEARABLES_ALLOC_BACKTRACE=1 in the
// environment, every counted allocation prints its call stack to stderr (symbols through
// backtrace_symbols_fd, which does not allocate), to find where the remaining ones are.
#include "sphere_contacts.hpp"
#include "tearables/world.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <new>
#include <string>
#include <vector>

#if defined(__SANITIZE_ADDRESS__)
#define TEARABLES_COUNT_ALLOCATIONS 0  // the sanitizer owns operator new and malloc
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define TEARABLES_COUNT_ALLOCATIONS 0
#endif
#endif
#ifndef TEARABLES_COUNT_ALLOCATIONS
#define TEARABLES_COUNT_ALLOCATIONS 1
#endif

#if TEARABLES_COUNT_ALLOCATIONS
#include <execinfo.h>
#include <unistd.h>
#endif

namespace {

std::atomic<bool> g_counting{false};
std::atomic<long> g_allocations{0};
bool g_backtrace = false;
thread_local bool t_inside = false;  // a counted allocation's own bookkeeping is not counted

void counted() {
    if (!g_counting.load(std::memory_order_relaxed) || t_inside) return;
    g_allocations.fetch_add(1, std::memory_order_relaxed);
#if TEARABLES_COUNT_ALLOCATIONS
    if (g_backtrace) {
        t_inside = true;
        void* frames[24];
        const int n = backtrace(frames, 24);
        static const char line[] = "---- heap allocation in a counted step:\n";
        (void)!write(2, line, sizeof line - 1);
        backtrace_symbols_fd(frames, n, 2);
        t_inside = false;
    }
#endif
}

/// Counts the heap allocations of the process (every thread) while alive.
struct AllocationCounter {
    AllocationCounter() {
        g_allocations = 0;
        g_counting = true;
    }
    ~AllocationCounter() { g_counting = false; }
    long count() const { return g_allocations.load(); }
};

}  // namespace

#if TEARABLES_COUNT_ALLOCATIONS
extern "C" {
void* __libc_malloc(std::size_t);
void* __libc_calloc(std::size_t, std::size_t);
void* __libc_realloc(void*, std::size_t);
void* malloc(std::size_t n) {
    counted();
    return __libc_malloc(n);
}
void* calloc(std::size_t k, std::size_t n) {
    counted();
    return __libc_calloc(k, n);
}
void* realloc(void* p, std::size_t n) {
    counted();
    return __libc_realloc(p, n);
}
}

// operator new and delete (all forms): counted, then to malloc / aligned_alloc (whose own
// count is suppressed, so that one allocation counts once).
namespace {
void* allocate(std::size_t n) {
    counted();
    t_inside = true;
    void* p = std::malloc(n ? n : 1);
    t_inside = false;
    return p;
}
void* allocateAligned(std::size_t n, std::align_val_t al) {
    counted();
    const auto a = static_cast<std::size_t>(al);
    t_inside = true;
    void* p = std::aligned_alloc(a, (n + a - 1) / a * a + (n ? 0 : a));
    t_inside = false;
    return p;
}
}  // namespace
void* operator new(std::size_t n) {
    if (void* p = allocate(n)) return p;
    throw std::bad_alloc();
}
void* operator new[](std::size_t n) {
    if (void* p = allocate(n)) return p;
    throw std::bad_alloc();
}
void* operator new(std::size_t n, const std::nothrow_t&) noexcept { return allocate(n); }
void* operator new[](std::size_t n, const std::nothrow_t&) noexcept { return allocate(n); }
void* operator new(std::size_t n, std::align_val_t al) {
    if (void* p = allocateAligned(n, al)) return p;
    throw std::bad_alloc();
}
void* operator new[](std::size_t n, std::align_val_t al) {
    if (void* p = allocateAligned(n, al)) return p;
    throw std::bad_alloc();
}
void* operator new(std::size_t n, std::align_val_t al, const std::nothrow_t&) noexcept { return allocateAligned(n, al); }
void* operator new[](std::size_t n, std::align_val_t al, const std::nothrow_t&) noexcept { return allocateAligned(n, al); }
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }
void operator delete(void* p, const std::nothrow_t&) noexcept { std::free(p); }
void operator delete[](void* p, const std::nothrow_t&) noexcept { std::free(p); }
void operator delete(void* p, std::align_val_t) noexcept { std::free(p); }
void operator delete[](void* p, std::align_val_t) noexcept { std::free(p); }
void operator delete(void* p, std::size_t, std::align_val_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept { std::free(p); }
void operator delete(void* p, std::align_val_t, const std::nothrow_t&) noexcept { std::free(p); }
void operator delete[](void* p, std::align_val_t, const std::nothrow_t&) noexcept { std::free(p); }
#endif

namespace {

using tearables::StringDesc;
using tearables::StringId;
using tearables::Vec3;
using tearables::World;

constexpr int kWarmUp = 50;   // steps before counting: every buffer has grown
constexpr int kCounted = 50;  // steps counted

void prepare() {
#if TEARABLES_COUNT_ALLOCATIONS
    const char* env = std::getenv("TEARABLES_ALLOC_BACKTRACE");
    g_backtrace = env && env[0] == '1';
    if (g_backtrace) {  // backtrace() loads libgcc on its first call (which allocates)
        void* frames[4];
        backtrace(frames, 4);
    }
#else
    GTEST_SKIP() << "built with a sanitizer: it replaces operator new and malloc itself";
#endif
}

/// Segments of 1 g, 5 mm radius (the benchmark's rope) and a tip of `tip` kg.
StringDesc rope(const Vec3& from, const Vec3& to, int segments, double tip = 0.01) {
    StringDesc d = StringDesc::straight(from, to, segments);
    d.radius = 0.005;
    d.density = 0.001 / (3.14159265358979 * d.radius * d.radius * ((to - from).norm() / segments));
    d.particle_masses = {{-1, tip}};
    return d;
}

/// Smallest distance between the axes of a's and b's segments, sampled (enough to tell
/// whether two ropes touch).
double closestApproach(const World& world, StringId a, StringId b) {
    const auto& xa = *world.view(a).positions;
    const auto& xb = *world.view(b).positions;
    double best = 1e300;
    for (const Vec3& p : xa)
        for (std::size_t k = 0; k + 1 < xb.size(); ++k) {
            const Vec3 d = xb[k + 1] - xb[k];
            const double t = std::clamp((p - xb[k]).dot(d) / d.squaredNorm(), 0.0, 1.0);
            best = std::min(best, (p - (xb[k] + t * d)).norm());
        }
    return best;
}

/// Steps `world` kWarmUp times, then counts the allocations of kCounted steps.
long countedSteps(World& world) {
    for (int i = 0; i < kWarmUp; ++i) world.step(0.01);
    AllocationCounter counter;
    for (int i = 0; i < kCounted; ++i) world.step(0.01);
    return counter.count();
}

/// What a counting test ran into: the allocations of its kCounted steps, and how to see where.
std::string allocationReport(long allocations) {
    return std::to_string(allocations) + " heap allocations in " + std::to_string(kCounted) +
           " steps (run with TEARABLES_ALLOC_BACKTRACE=1 to see where)";
}

}  // namespace

// The counter itself works (so that zero below means something).
TEST(StepAllocations, CounterSeesAnAllocation) {
    prepare();
    if (IsSkipped()) return;
    long n = 0;
    {
        AllocationCounter counter;
        auto* v = new std::vector<double>(100);
        n = counter.count();
        delete v;
    }
    EXPECT_GE(n, 2);  // the vector object and its buffer
}

// A rope pinned at one end with a heavy tip, let go 30 degrees from the vertical and
// swinging (prediction, shape matching, strain limit, twist, tension, material,
// velocities), beside a second, hanging one that it never reaches (the string-string pair
// search runs over both every step and finds the swept pairs along each rope, all dropped
// by the filter: no joint solve), on one and on two threads: not one allocation in 50
// steps.
TEST(StepAllocations, SwingingRopesStepWithoutAllocating) {
    prepare();
    if (IsSkipped()) return;
    for (int threads : {1, 2}) {
        tearables::WorldSettings settings;
        settings.threads = threads;
        World world(settings);
        const StringId a = world.addString(rope({0, 0, 0}, {0.2, -0.3464, 0}, 40, 0.4));
        world.attachToPoint(a, 0, {0, 0, 0});
        const StringId b = world.addString(rope({0, 0, 0.3}, {0, -0.4, 0.3}, 40));
        world.attachToPoint(b, 0, {0, 0, 0.3});
        const long allocations = countedSteps(world);
        EXPECT_EQ(allocations, 0) << threads << " threads: " << allocationReport(allocations);
        EXPECT_GT(closestApproach(world, a, b), 0.1);  // they never touched
    }
}

// One long rope alone (5000 segments, swinging down from the horizontal) on two threads:
// its stages split their own work over the pool (the strain limit's halves, shape
// matching's passes, the tension's loops, the chain tree's subtrees): no allocation either.
TEST(StepAllocations, LongRopeSplitOverTwoThreadsStepsWithoutAllocating) {
    prepare();
    if (IsSkipped()) return;
    tearables::WorldSettings settings;
    settings.threads = 2;
    World world(settings);
    const StringId a = world.addString(rope({0, 0, 0}, {50, 0, 0}, 5000, 5.0));
    world.attachToPoint(a, 0, {0, 0, 0});
    const long allocations = countedSteps(world);
    EXPECT_EQ(allocations, 0) << allocationReport(allocations);
}

// The same with string-string contacts: a rope pinned at one end swings down onto a rope
// stretched across its path and hangs draped over it; the contacts last through the
// counted steps. Until 2026-12-01 (disabled until then) detail::solveStringCluster made
// ~170 allocations a step here, all in its Woodbury step: Eigen's dynamic matrices keep no
// spare capacity, and the number of contact directions changes from step to step. Its
// scratch now keeps one set of matrices per size (ClusterScratch::Impl::woodbury).
TEST(StepAllocations, RopeDrapedOverAnotherStepsWithoutAllocating) {
    prepare();
    if (IsSkipped()) return;
    World world;
    const StringId hanging = world.addString(rope({0, 0, 0}, {0.4, 0, 0}, 40));
    world.attachToPoint(hanging, 0, {0, 0, 0});
    const StringId across = world.addString(rope({0.2, -0.08, -0.2}, {0.2, -0.08, 0.2}, 40));
    world.attachToPoint(across, 0, {0.2, -0.08, -0.2});
    world.attachToPoint(across, -1, {0.2, -0.08, 0.2});
    const long allocations = countedSteps(world);
    // The ropes touch (axes 1 cm apart, the two radii, within the 10% the world counts as
    // touching) at the end of the counted steps.
    EXPECT_LT(closestApproach(world, hanging, across), 0.011);
    EXPECT_EQ(allocations, 0) << "with string contacts: " << allocationReport(allocations);
}

// Rigid contacts: a rope pinned at both ends sagging onto a movable ball (1 kg: the body's
// six unknowns in the rope's solve, the Schur complement on them, friction passes); the
// contacts last through the counted steps. The ball is moved by the rope only (no host
// integrates it here). Not one allocation: the solve keeps its scratch in the string.
// (Until 2026-12-01 the rope was free, draped over the ball; it slid along the ball by
// between -0.1 and +0.33 m in 100 steps depending on rounding (starts shifted by 1e-12 m
// gave either), so whether it still touched at the end was a coin toss. The pins keep the
// contacts; the step in which that free rope left the ball allocated once, see
// World::addString.)
TEST(StepAllocations, RopeDrapedOverAMovableBallStepsWithoutAllocating) {
    prepare();
    if (IsSkipped()) return;
    tearables::WorldSettings settings;
    settings.rigid_contacts = true;
    World world(settings);
    tearables::RigidState ball;
    ball.position = {0, -0.2, 0};
    ball.inverse_mass = 1.0;
    ball.inverse_inertia_local = tearables::Mat3::Identity() * (1.0 / (0.4 * 0.2 * 0.2));
    const tearables::RigidId id = world.addRigid(ball);
    tearables::testing::SphereContacts contacts(id, world, 0.2, 0.4);
    world.setContactProvider(&contacts);
    const StringId a = world.addString(rope({-0.3, 0.01, 0}, {0.3, 0.01, 0}, 40, 0.001));
    world.attachToPoint(a, 0, {-0.3, 0.01, 0});
    world.attachToPoint(a, -1, {0.3, 0.01, 0});
    const long allocations = countedSteps(world);
    bool touching = false;
    for (const auto& c : world.lastContacts()) touching = touching || c.string == a;
    EXPECT_TRUE(touching);
    EXPECT_EQ(allocations, 0) << allocationReport(allocations);
}

// A cloth of 12 x 12 vertices swinging from two corners (prediction, the strain limit's
// Newton iterations with their sparse factorisations, the least-squares tension solve,
// material response, velocities): not one allocation once running.
TEST(StepAllocations, SwingingClothStepsWithoutAllocating) {
    prepare();
    if (IsSkipped()) return;
    World world;
    tearables::ClothDesc d;
    d.corner = tearables::Vec3(0.0, 1.0, 0.0);
    d.resolution = {12, 12};
    d.size = {0.11, 0.11};
    d.attachments = {{d.vertex(0, 0)}, {d.vertex(-1, 0)}};
    world.addCloth(d);
    const long allocations = countedSteps(world);
    EXPECT_EQ(allocations, 0) << allocationReport(allocations);
}

// A paper sheet of 16 x 16 vertices hanging from two corners (implicit Jacobi solve,
// hinge and crease checks, tension estimates), with its edge tensions from the springs'
// stretch and from momentum balance (the normal equations' sparse factorisation, its
// pattern kept while the sheet's springs are the same): not one allocation once running.
// (Until 2026-12-02 the momentum tension allocated ~54 times a step: its vectors, its
// matrix and Eigen's conjugate gradients were made anew every step.)
TEST(StepAllocations, HangingPaperStepsWithoutAllocating) {
    prepare();
    if (IsSkipped()) return;
    for (const tearables::PaperTension tension : {tearables::PaperTension::Stretch, tearables::PaperTension::Momentum}) {
        World world;
        tearables::PaperDesc d;
        d.resolution[0] = 16;
        d.resolution[1] = 16;
        d.size[0] = 0.15;
        d.size[1] = 0.15;
        d.tension = tension;
        const tearables::PaperId id = world.addPaper(d);
        world.attachPaperToPoint(id, static_cast<std::uint32_t>(d.gridVertex(0, 0)), world.viewPaper(id).positions->at(d.gridVertex(0, 0)));
        world.attachPaperToPoint(id, static_cast<std::uint32_t>(d.gridVertex(15, 0)), world.viewPaper(id).positions->at(d.gridVertex(15, 0)));
        const long allocations = countedSteps(world);
        EXPECT_EQ(allocations, 0) << (tension == tearables::PaperTension::Momentum ? "momentum tension: " : "stretch tension: ")
                                  << allocationReport(allocations);
    }
}
