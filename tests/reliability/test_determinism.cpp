// Issue 8, determinism: the same scene and seed give a bit-identical trace, event list
// and final-state digest, run after run: in one process with fresh worlds, and through
// the command line. The scene tears one rope by tension and one by torsion, a ball lands
// on a rope (rigid collision), a crate is spawned and the wind is seeded and gusty. A
// second scene has the meshes: a cloth torn while holding a glued weight, a sheet
// creased by a ball and then torn while holding another.
#include "tearables/scene.hpp"

#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

namespace {

namespace fs = std::filesystem;
using tearables::scene::RunOptions;
using tearables::scene::RunResult;

const std::string kScene = std::string(TEARABLES_SOURCE_DIR) + "/tests/reliability/scenes/tear-twist-collide.json";
constexpr long long kSteps = 120;  // both tears (steps ~55, ~68) and the ball on the bridge (steps 35-80)
const std::string kMeshScene = std::string(TEARABLES_SOURCE_DIR) + "/tests/reliability/scenes/cloth-paper.json";
constexpr long long kMeshSteps = 160;  // cloth tears from step 17, paper creases from 11 and tears from 71

std::string slurp(const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    std::ostringstream s;
    s << in.rdbuf();
    return s.str();
}

fs::path outDir(const std::string& name) {
    const fs::path dir = fs::path(TEARABLES_TEST_OUT) / ("determinism-" + name);
    fs::remove_all(dir);
    return dir;
}

TEST(Determinism, SameSceneTwiceInProcessIsBitIdentical) {
    const tearables::scene::Scene scene = tearables::scene::loadSceneFile(kScene);
    RunOptions options;
    options.steps = kSteps;
    options.out_dir = outDir("a").string();
    const RunResult a = tearables::scene::runScene(scene, options);
    options.out_dir = outDir("b").string();
    const RunResult b = tearables::scene::runScene(tearables::scene::loadSceneFile(kScene), options);

    EXPECT_EQ(a.digest, b.digest);
    EXPECT_EQ(a.event_counts, b.event_counts);
    // The trace writes every particle, tension, twist and body pose each step with
    // round-trip precision: equal text is equal bits.
    const std::string trace_a = slurp(fs::path(options.out_dir).parent_path() / "determinism-a" / "trace.jsonl");
    const std::string trace_b = slurp(fs::path(options.out_dir) / "trace.jsonl");
    ASSERT_GT(trace_a.size(), 100000u);
    EXPECT_TRUE(trace_a == trace_b) << "traces differ";
    const std::string events_a = slurp(fs::path(options.out_dir).parent_path() / "determinism-a" / "events.jsonl");
    EXPECT_EQ(events_a, slurp(fs::path(options.out_dir) / "events.jsonl"));

    // The scene does what it is for: a tear by tension, a tear by torsion, a contact.
    EXPECT_NE(events_a.find(R"("cause":"tension","object":"weak")"), std::string::npos) << events_a;
    EXPECT_NE(events_a.find(R"("cause":"torsion","object":"twisted")"), std::string::npos) << events_a;
    std::istringstream lines(trace_a);
    std::string line;
    for (int i = 0; i <= 60 && std::getline(lines, line); ++i) {
    }
    // Frame 60: the ball (r 0.08) rests on the bridge rope at y = 1 instead of falling through.
    const auto ball = line.find(R"("ball":{"p":[)");
    ASSERT_NE(ball, std::string::npos);
    const double y = std::stod(line.substr(line.find(',', ball + 13) + 1));
    EXPECT_GT(y, 0.95) << line.substr(ball, 80);
}

/// Runs `scene` twice through the command line; the digests and traces must be equal.
void expectSameThroughTheCommandLine(const std::string& scene, long long steps, const std::string& name) {
    std::string summaries[2], traces[2];
    for (int run = 0; run < 2; ++run) {
        const fs::path dir = outDir(name + "-" + std::to_string(run));
        const std::string command = std::string(TEARABLES_CLI) + " run " + scene + " --out " + dir.string() +
                                    " --steps " + std::to_string(steps) + " --quiet";
        ASSERT_EQ(std::system(command.c_str()), 0) << command;
        summaries[run] = slurp(dir / "summary.json");
        traces[run] = slurp(dir / "trace.jsonl");
    }
    auto digest = [](const std::string& summary) {
        const auto at = summary.find("\"digest\": \"");
        return at == std::string::npos ? std::string() : summary.substr(at + 11, 16);
    };
    ASSERT_EQ(digest(summaries[0]).size(), 16u) << summaries[0];
    EXPECT_EQ(digest(summaries[0]), digest(summaries[1]));
    EXPECT_TRUE(traces[0] == traces[1]) << "traces differ";
}

TEST(Determinism, SameSceneTwiceThroughTheCommandLineHasTheSameDigest) {
    expectSameThroughTheCommandLine(kScene, kSteps, "cli");
}

TEST(Determinism, ClothAndPaperSceneTwiceInProcessIsBitIdentical) {
    RunOptions options;
    options.steps = kMeshSteps;
    options.out_dir = outDir("mesh-a").string();
    const RunResult a = tearables::scene::runScene(tearables::scene::loadSceneFile(kMeshScene), options);
    const fs::path dir_a = options.out_dir;
    options.out_dir = outDir("mesh-b").string();
    const RunResult b = tearables::scene::runScene(tearables::scene::loadSceneFile(kMeshScene), options);

    EXPECT_EQ(a.digest, b.digest);
    EXPECT_EQ(a.event_counts, b.event_counts);
    const std::string trace_a = slurp(dir_a / "trace.jsonl"), trace_b = slurp(fs::path(options.out_dir) / "trace.jsonl");
    ASSERT_GT(trace_a.size(), 100000u);
    EXPECT_TRUE(trace_a == trace_b) << "traces differ";
    const std::string events_a = slurp(dir_a / "events.jsonl");
    EXPECT_EQ(events_a, slurp(fs::path(options.out_dir) / "events.jsonl"));

    // The scene does what it is for: the cloth tears, the sheet creases and tears.
    EXPECT_NE(events_a.find(R"("cause":"tension","object":"cloth","segment")"), std::string::npos) << events_a.substr(0, 2000);
    EXPECT_NE(events_a.find(R"("type":"tear")"), std::string::npos);
    EXPECT_NE(events_a.find(R"("cause":"compression","compression":)"), std::string::npos) << "no crease";
    EXPECT_NE(events_a.find(R"("cause":"tension","object":"paper")"), std::string::npos) << "no paper tear";
    std::istringstream lines(events_a);
    std::string line;
    int cloth_tears = 0, paper_tears = 0, creases = 0;
    while (std::getline(lines, line)) {
        const bool tear = line.find(R"("type":"tear")") != std::string::npos;
        cloth_tears += tear && line.find(R"("object":"cloth")") != std::string::npos;
        paper_tears += tear && line.find(R"("object":"paper")") != std::string::npos;
        creases += line.find(R"("type":"crease")") != std::string::npos;
    }
    EXPECT_GE(cloth_tears, 5);
    EXPECT_GE(paper_tears, 5);
    EXPECT_GE(creases, 5);
    std::printf("cloth-paper: %d cloth tears, %d creases, %d paper tears\n", cloth_tears, creases, paper_tears);
}

TEST(Determinism, ClothAndPaperSceneTwiceThroughTheCommandLineHasTheSameDigest) {
    expectSameThroughTheCommandLine(kMeshScene, kMeshSteps, "cli-mesh");
}

}  // namespace

#include "long_rope.hpp"
#include "tearables/world.hpp"

#include <cstring>
#include <vector>

namespace {

// Ropes that swing, fall across each other and tear, stepped on `threads` threads; every
// particle's position after the run, as bytes.
std::vector<double> runRopes(int threads) {
    tearables::WorldSettings settings;
    settings.threads = threads;
    tearables::World world(settings);
    std::vector<tearables::StringId> ids;
    for (int i = 0; i < 7; ++i) {
        const tearables::Vec3 start(0.0, 0.02 * i, 0.03 * i);
        auto desc = tearables::StringDesc::straight(start, start + tearables::Vec3(0.4, 0.0, 0.1 * (i % 3)), 40);
        desc.radius = 0.004;
        desc.seed = static_cast<std::uint64_t>(i);
        desc.particle_masses = {{-1, 0.5 + 0.5 * i}};
        ids.push_back(world.addString(desc));
        world.attachToPoint(ids.back(), 0, start);
        if (i % 2) world.attachToPoint(ids.back(), -1, start + tearables::Vec3(0.3, 0.0, 0.0));
    }
    for (int step = 0; step < 100; ++step) world.step(0.01);
    std::vector<double> out;
    for (const auto id : ids)
        for (const auto& x : *world.view(id).positions) out.insert(out.end(), {x.x(), x.y(), x.z()});
    return out;
}

}  // namespace

// WorldSettings::threads changes who steps a string, never what it computes.
TEST(Determinism, ThreadCountDoesNotChangeOneBit) {
    const std::vector<double> one = runRopes(1);
    for (int threads : {2, 3, 0}) {
        const std::vector<double> many = runRopes(threads);
        ASSERT_EQ(one.size(), many.size());
        EXPECT_EQ(0, std::memcmp(one.data(), many.data(), one.size() * sizeof(double))) << threads << " threads";
    }
}

namespace {

// One rope long enough (5001 particles) that a stage splits its own work over the pool
// (the strain limit's two sweeps, shape matching's passes); the thread count may change
// between steps.
std::vector<double> runLongRope(const std::vector<int>& threads_per_step) {
    tearables::WorldSettings settings;
    settings.threads = threads_per_step.front();
    tearables::World world(settings);
    const auto id = tearables::testing::addLongRope(world);
    for (int threads : threads_per_step) {
        world.settings().threads = threads;
        world.step(0.01);
    }
    std::vector<double> out;
    for (const auto& x : *world.view(id).positions) out.insert(out.end(), {x.x(), x.y(), x.z()});
    for (double t : *world.view(id).tension) out.push_back(t);
    return out;
}

}  // namespace

// A long rope's stages split over the threads compute what one thread computes, and a
// thread count changed between steps (the pool restarts) changes nothing either.
TEST(Determinism, LongRopeSplitOverThreadsDoesNotChangeOneBit) {
    const std::vector<double> one = runLongRope(std::vector<int>(12, 1));
    const std::vector<std::vector<int>> runs = {std::vector<int>(12, 2), {2, 3, 2, 1, 2, 2, 3, 3, 1, 2, 2, 2}};
    for (const std::vector<int>& threads : runs) {
        const std::vector<double> many = runLongRope(threads);
        ASSERT_EQ(one.size(), many.size());
        EXPECT_EQ(0, std::memcmp(one.data(), many.data(), one.size() * sizeof(double))) << threads.front() << " threads first";
    }
}

namespace {

// Two runs' events field by field (the stress bit for bit); `threads`: the second run's.
void expectSameEvents(const std::vector<tearables::Event>& one, const std::vector<tearables::Event>& many, int threads) {
    ASSERT_EQ(one.size(), many.size()) << threads << " threads";
    for (std::size_t i = 0; i < one.size(); ++i) {
        EXPECT_EQ(one[i].type, many[i].type) << i;
        EXPECT_EQ(one[i].cause, many[i].cause) << i;
        EXPECT_EQ(one[i].segment, many[i].segment) << i;
        EXPECT_EQ(one[i].step, many[i].step) << i;
        EXPECT_EQ(0, std::memcmp(&one[i].stress, &many[i].stress, sizeof(double))) << i;
    }
}

// The long rope pulled at particle 2600 by 5 kN (about its rupture load) for a step after
// three of settling: every event of the four steps, field by field.
std::vector<tearables::Event> longRopeEvents(int threads) {
    tearables::WorldSettings settings;
    settings.threads = threads;
    tearables::World world(settings);
    const auto id = tearables::testing::addLongRope(world);
    std::vector<tearables::Event> events;
    for (int step = 0; step < 4; ++step) {
        if (step == 3) world.applyForce(id, 2600, {0.0, 5000.0, 0.0});
        world.step(0.01);
        events.insert(events.end(), world.events().begin(), world.events().end());
    }
    return events;
}

}  // namespace

// The material stage of a long rope runs on the pool in ranges of segments (each with its
// own yield events and most overloaded segment, merged in order): the events, their order
// and the torn segment are those of one thread.
TEST(Determinism, LongRopeYieldAndTearEventsDoNotDependOnThreads) {
    const std::vector<tearables::Event> one = longRopeEvents(1);
    std::size_t yields = 0, tears = 0;
    for (const auto& e : one) {
        yields += e.type == tearables::EventType::Yield;
        tears += e.type == tearables::EventType::Tear;
    }
    ASSERT_GT(yields, 1u);
    ASSERT_EQ(tears, 1u);
    for (int threads : {2, 3}) {
        const std::vector<tearables::Event> many = longRopeEvents(threads);
        expectSameEvents(one, many, threads);
    }
}

namespace {

// A 5000-segment rope clamped at both ends and turned at one until it tears by torsion:
// every event (the joints' torsional yields, then the tear), step by step.
std::vector<tearables::Event> twistedLongRopeEvents(int threads) {
    tearables::WorldSettings settings;
    settings.threads = threads;
    tearables::World world(settings);
    auto desc = tearables::StringDesc::straight({0, 0, 0}, {50.0, 0.0, 0.0}, 5000);
    desc.material.torsion.yield = 1e-4;
    desc.material.torsion.rupture = 2e-4;  // r theta / L with r = 2 mm, L = 50 m: 5 rad
    const auto id = world.addString(desc);
    world.attachToPoint(id, 0, {0, 0, 0});
    world.attachToPoint(id, -1, {50.0, 0.0, 0.0});
    std::vector<tearables::Event> events;
    for (int step = 0; step < 40; ++step) {
        world.turnEnd(id, -1, 0.5);
        world.step(0.01);
        events.insert(events.end(), world.events().begin(), world.events().end());
        if (!events.empty() && events.back().type == tearables::EventType::Tear) break;
    }
    return events;
}

}  // namespace

// The material stage's torsion loops run in ranges on the pool as its tension loop does:
// the same yields and the same torsional tear on 1, 2 and 3 threads.
TEST(Determinism, LongRopeTorsionEventsDoNotDependOnThreads) {
    const std::vector<tearables::Event> one = twistedLongRopeEvents(1);
    ASSERT_GT(one.size(), 1u);
    EXPECT_EQ(one.back().type, tearables::EventType::Tear);
    EXPECT_EQ(one.back().cause, tearables::EventCause::Torsion);
    for (int threads : {2, 3}) {
        const std::vector<tearables::Event> many = twistedLongRopeEvents(threads);
        expectSameEvents(one, many, threads);
    }
}
