// The red-team corpus: each scene in tests/reliability/redteam/ states on its first line
// what must happen to it, and this test checks it.
//   // expect: refused PATH   loading or starting it throws InvalidInput naming exactly PATH
//   // expect: runs           it runs; every particle's position and velocity stays finite
//                             and no faster than max_speed (500 m/s) at every frame, no
//                             position or velocity in the trace is null, and a clamped
//                             shot says so in its event
// Plus the API probes of the same report: --steps out of range, lastError() after a
// failed then a successful step.
#include "tearables/bullet_core.hpp"
#include "tearables/scene.hpp"
#include "tearables/world.hpp"

#include "plugin/bullet_fixture.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cctype>
#include <climits>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <sys/wait.h>
#include <vector>

namespace {

namespace fs = std::filesystem;
using tearables::InvalidInput;
using tearables::Vec3;
using namespace tearables::scene;

const fs::path kCorpus = fs::path(TEARABLES_SOURCE_DIR) / "tests/reliability/redteam";
constexpr double kMaxSpeed = 500.0;  // WorldSettings::max_speed's default, which scenes use

std::string slurp(const fs::path& p) {
    std::ifstream in(p);
    std::stringstream s;
    s << in.rdbuf();
    return s.str();
}

std::vector<std::string> corpus() {
    std::vector<std::string> names;
    for (const auto& entry : fs::directory_iterator(kCorpus))
        if (entry.path().extension() == ".json") names.push_back(entry.path().stem().string());
    std::sort(names.begin(), names.end());
    return names;
}

/// The expectation on the file's first line: "refused PATH" or "runs".
std::string expectation(const fs::path& file) {
    std::ifstream in(file);
    std::string line;
    std::getline(in, line);
    const std::string prefix = "// expect: ";
    if (line.rfind(prefix, 0) != 0) return "";
    return line.substr(prefix.size());
}

/// Every vector finite and no longer than `max`.
void expectBounded(const std::vector<Vec3>& v, double max, const std::string& what) {
    for (std::size_t i = 0; i < v.size(); ++i) {
        ASSERT_TRUE(v[i].allFinite()) << what << " " << i;
        ASSERT_LE(v[i].norm(), max * (1.0 + 1e-12)) << what << " " << i;
    }
}

class RedTeam : public ::testing::TestWithParam<std::string> {};

TEST_P(RedTeam, MeetsItsExpectation) {
    const fs::path file = kCorpus / (GetParam() + ".json");
    const std::string expect = expectation(file);
    ASSERT_FALSE(expect.empty()) << file << " has no '// expect:' first line";
    const fs::path out = fs::path(TEARABLES_TEST_OUT) / "redteam" / GetParam();
    fs::remove_all(out);
    RunOptions options;
    options.out_dir = out.string();
    options.on_frame = [](const FrameState& f) {
        for (const FrameString& s : f.strings) {
            expectBounded(*s.view.positions, 1e300, s.name + " position");
            expectBounded(*s.view.velocities, kMaxSpeed, s.name + " velocity");
        }
        for (const FrameCloth& c : f.cloths) {
            expectBounded(*c.view.positions, 1e300, c.name + " position");
            expectBounded(*c.view.velocities, kMaxSpeed, c.name + " velocity");
        }
        for (const FramePaper& p : f.papers) {
            expectBounded(*p.view.positions, 1e300, p.name + " position");
            expectBounded(*p.view.velocities, kMaxSpeed, p.name + " velocity");
        }
        for (const FrameBody& b : f.bodies) ASSERT_TRUE(b.position.allFinite() && b.orientation.coeffs().allFinite()) << b.name;
    };
    if (expect.rfind("refused ", 0) == 0) {
        const std::string path = expect.substr(8);
        try {
            runScene(loadSceneFile(file.string()), options);
            FAIL() << "accepted; expected a refusal at " << path;
        } catch (const InvalidInput& e) {
            EXPECT_EQ(e.field(), path) << e.what();
        }
        EXPECT_FALSE(fs::exists(out / "trace.jsonl")) << "nothing is simulated";
        return;
    }
    ASSERT_EQ(expect, "runs");
    const Scene scene = loadSceneFile(file.string());
    const RunResult r = runScene(scene, options);
    EXPECT_EQ(r.steps, scene.steps);
    const std::string trace = slurp(out / "trace.jsonl");
    ASSERT_FALSE(trace.empty());
    // No null (a non-finite number) in any position, orientation or velocity (a tension
    // is null where its segment is broken: that is the format), and bodies no faster than
    // a shot's clamp plus what gravity adds since.
    const auto numbers = [](const nlohmann::json& list) {
        for (const auto& n : list)
            if (n.is_array() ? std::any_of(n.begin(), n.end(), [](const auto& c) { return !c.is_number(); }) : !n.is_number())
                return false;
        return true;
    };
    std::istringstream frames(trace);
    for (std::string line; std::getline(frames, line);) {
        const auto frame = nlohmann::json::parse(line);
        for (const char* kind : {"strings", "cloths", "papers"})
            if (frame.contains(kind))
                for (const auto& [name, o] : frame[kind].items()) EXPECT_TRUE(numbers(o["x"])) << name << ": " << line.substr(0, 200);
        if (!frame.contains("bodies")) continue;
        const double t = frame["t"].get<double>();
        for (const auto& [name, b] : frame["bodies"].items()) {
            for (const char* k : {"p", "q", "v"}) ASSERT_TRUE(numbers(b[k])) << name << "." << k;
            const Vec3 v(b["v"][0].get<double>(), b["v"][1].get<double>(), b["v"][2].get<double>());
            EXPECT_LE(v.norm(), kMaxSpeed + scene.gravity.norm() * t + 1e-3) << name << " at t = " << t;
        }
    }
    // A shot larger than the clamp reports the impulse given and the one asked for.
    for (const Driver& d : scene.drivers) {
        if (d.type != Driver::Type::Shoot) continue;
        std::istringstream events(slurp(out / "events.jsonl"));
        int clamped = 0;
        for (std::string line; std::getline(events, line);) {
            const auto e = nlohmann::json::parse(line);
            if (e["type"] != "shot" || !e.value("hit", false)) continue;
            if (e.contains("clamped_from")) {
                ++clamped;
                EXPECT_EQ(e["clamped_from"].get<double>(), d.impulse);
                EXPECT_LT(e["impulse"].get<double>(), d.impulse);
            }
        }
        EXPECT_EQ(clamped, static_cast<int>(d.times.size()));
    }
}

INSTANTIATE_TEST_SUITE_P(Corpus, RedTeam, ::testing::ValuesIn(corpus()),
                         [](const ::testing::TestParamInfo<std::string>& info) {
                             std::string name = info.param;
                             std::replace_if(name.begin(), name.end(), [](char c) { return !std::isalnum(static_cast<unsigned char>(c)); }, '_');
                             return name;
                         });

// --steps past the scenes' own bound is refused by the CLI (exit 2), before anything runs.
TEST(RedTeamProbes, StepsOutOfRangeIsRefused) {
    const fs::path dir = fs::path(TEARABLES_TEST_OUT) / "redteam-cli";
    fs::create_directories(dir);
    const fs::path err = dir / "stderr.txt";
    for (const char* steps : {"9223372036854775808", "1000000001", "-1"}) {
        const std::string cmd = std::string(TEARABLES_CLI) + " run " + (kCorpus / "shoot-1e6.json").string() + " --quiet --out " +
                                (dir / "out").string() + " --steps " + steps + " 2>" + err.string() + " >/dev/null";
        const int raw = std::system(cmd.c_str());
        ASSERT_TRUE(WIFEXITED(raw));
        EXPECT_EQ(WEXITSTATUS(raw), 2) << steps;
        EXPECT_NE(slurp(err).find("--steps"), std::string::npos) << slurp(err);
    }
    RunOptions options;
    options.steps = LLONG_MAX;
    try {
        runScene(loadSceneFile((kCorpus / "shoot-1e6.json").string()), options);
        FAIL() << "--steps " << LLONG_MAX << " accepted";
    } catch (const InvalidInput& e) {
        EXPECT_EQ(e.field(), "--steps");
    }
}

// lastError() holds a failed step's message and is cleared by the next step that succeeds.
TEST(RedTeamProbes, LastErrorClearsAfterASuccessfulStep) {
    tearables::testing::Physics phys;
    tearables::BulletWorld ropes(*phys.world);
    ropes.addString(tearables::StringDesc::straight({0, 2, 0}, {0, 1, 0}, 5));
    ropes.core().settings().max_speed = -1.0;  // refused by the step, which changes nothing
    phys.step(1);
    EXPECT_NE(ropes.lastError().find("max_speed"), std::string::npos) << ropes.lastError();
    ropes.core().settings().max_speed = 500.0;
    phys.step(1);
    EXPECT_EQ(ropes.lastError(), "");
}

// A force of 1e200 N on one vertex of a sheet, every step (finite, so the API takes it):
// the sheet never stops silently. Either it freezes, with exactly one Freeze event naming
// it, or it goes on: the pushed vertex rises, no vertex faster than max_speed.
TEST(RedTeamProbes, HugeForceOnOnePaperVertexNeverStopsTheSheetSilently) {
    tearables::World world;
    tearables::PaperDesc d;
    d.name = "sheet";
    d.center = Vec3(0, 1, 0);
    d.size[0] = d.size[1] = 0.2;
    d.resolution[0] = d.resolution[1] = 5;
    const tearables::PaperId id = world.addPaper(d);
    int freezes = 0;
    for (int k = 0; k < 10; ++k) {
        world.applyPaperForce(id, 12, Vec3(0, 1e200, 0));
        world.step(0.01);
        for (const auto& e : world.events())
            if (e.type == tearables::EventType::Freeze) {
                ++freezes;
                EXPECT_EQ(e.object, "sheet");
            }
    }
    const tearables::PaperView v = world.viewPaper(id);
    for (const Vec3& x : *v.positions) ASSERT_TRUE(x.allFinite());
    if (v.frozen) {
        EXPECT_EQ(freezes, 1);
        return;
    }
    EXPECT_EQ(freezes, 0);
    EXPECT_GT((*v.positions)[12].y(), 1.1);  // pushed up for 0.1 s
    expectBounded(*v.velocities, kMaxSpeed, "sheet velocity");
}

// The same for a cloth: 1e200 N on its middle vertex every step.
TEST(RedTeamProbes, HugeForceOnOneClothVertexNeverStopsTheClothSilently) {
    tearables::World world;
    tearables::ClothDesc d;
    d.name = "cloth";
    d.corner = Vec3(0, 1, 0);
    d.size = {0.2, 0.2};
    d.resolution = {5, 5};
    const tearables::ClothId id = world.addCloth(d);
    int freezes = 0;
    for (int k = 0; k < 10; ++k) {
        world.applyClothForce(id, 12, Vec3(0, 1e200, 0));
        world.step(0.01);
        for (const auto& e : world.events()) freezes += e.type == tearables::EventType::Freeze;
    }
    const tearables::ClothView v = world.viewCloth(id);
    for (const Vec3& x : *v.positions) ASSERT_TRUE(x.allFinite());
    if (v.frozen) {
        EXPECT_EQ(freezes, 1);
        return;
    }
    EXPECT_EQ(freezes, 0);
    EXPECT_GT((*v.positions)[12].y(), 1.1);  // pushed up for 0.1 s
    expectBounded(*v.velocities, kMaxSpeed, "cloth velocity");
}

/// The argument name an API call's refusal gives, or "" when it was accepted.
template <class Call>
std::string refusal(Call&& call) {
    try {
        call();
    } catch (const InvalidInput& e) {
        return e.field();
    }
    return "";
}

// The API holds positions to the scene format's bound (1e6 m along each axis) and names
// the argument; what was refused leaves nothing behind.
TEST(RedTeamProbes, ApiPositionsPastTheBoundAreRefusedByName) {
    tearables::World world;
    const tearables::StringId rope = world.addString(tearables::StringDesc::straight({0, 2, 0}, {0, 1, 0}, 5));
    EXPECT_EQ(refusal([&] { world.attachToPoint(rope, 0, Vec3(0, 1e300, 0)); }), "point");
    EXPECT_FALSE(world.isAttached(rope, 0));
    tearables::StringDesc far = tearables::StringDesc::straight({0, 2, 0}, {0, 1, 0}, 5);
    far.points[3].x() = 2e6;
    EXPECT_EQ(refusal([&] { world.addString(far); }), "points[3]");
    tearables::ClothDesc cloth;
    cloth.name = "cloth";
    cloth.corner = Vec3(1e300, 0, 0);
    EXPECT_EQ(refusal([&] { world.addCloth(cloth); }), "corner");
    cloth.corner = Vec3(0, 0, 0);
    cloth.size = {1e300, 1.0};
    EXPECT_EQ(refusal([&] { world.addCloth(cloth); }), "size");
    tearables::PaperDesc paper;
    paper.center = Vec3(0, 0, -1e300);
    EXPECT_EQ(refusal([&] { world.addPaper(paper); }), "center");
    paper.center = Vec3(0, 0, 0);
    const tearables::PaperId sheet = world.addPaper(paper);
    EXPECT_EQ(refusal([&] { world.attachPaperToPoint(sheet, 0, Vec3(1e7, 0, 0)); }), "point");
    EXPECT_EQ(world.strings().size(), 1u);
    EXPECT_TRUE(world.cloths().empty());
    world.step(0.01);
    for (const Vec3& x : *world.view(rope).positions) EXPECT_TRUE(x.allFinite());
}

}  // namespace

// Resource limits: the estimate names the field of the object that costs most, a raised
// limit lets the same scene through, and the CLI refuses a limit it cannot read (exit 2,
// naming the flag) before anything runs.
TEST(RedTeamProbes, ResourceLimitsNameTheCostliestFieldAndCanBeRaised) {
    const Scene cloth = loadSceneFile((kCorpus / "cloth-500x500.json").string());
    const ResourceEstimate e = estimateResources(cloth);
    EXPECT_EQ(e.memory_field, "cloths[0].resolution");
    EXPECT_EQ(e.step_field, "cloths[0].resolution");
    // Past the default limit, and within 10% of the 5.7 GB the issue measured for one step.
    EXPECT_GT(e.memory_bytes, 4e9);
    EXPECT_LT(e.memory_bytes, 1.1 * 5.7e9);
    ResourceLimits raised;
    raised.memory_bytes = 8e9;
    raised.step_seconds = 1e3;
    EXPECT_NO_THROW(checkResources(cloth, raised));
    raised.step_seconds = 1.0;
    try {
        checkResources(cloth, raised);
        FAIL() << "a 500 x 500 cloth's step estimated within 1 s";
    } catch (const InvalidInput& e) {
        EXPECT_EQ(e.field(), "cloths[0].resolution");
        EXPECT_NE(std::string(e.what()).find("--max-step-seconds"), std::string::npos) << e.what();
    }
    // A string given by its points is blamed on them.
    Scene thick;
    String s;
    for (int i = 0; i <= 100000; ++i) s.desc.points.push_back(Vec3(1e-6 * i, 1, 0));
    s.desc.radius = 0.004;
    s.geometry_field = "points";
    thick.strings.push_back(s);
    try {
        checkResources(thick, ResourceLimits{});
        FAIL() << "1e5 segments of 1 um, 4 mm thick, accepted";
    } catch (const InvalidInput& e) {
        EXPECT_EQ(e.field(), "strings[0].points");
    }
    // Every built-in scene is well within the defaults.
    for (const auto& [name, description] : builtinScenes()) {
        const ResourceEstimate b = estimateResources(parseScene(*builtinSceneText(name)));
        EXPECT_LT(b.memory_bytes, 0.5 * ResourceLimits{}.memory_bytes) << name;
        EXPECT_LT(b.step_seconds, 0.1 * ResourceLimits{}.step_seconds) << name;
    }
    const fs::path dir = fs::path(TEARABLES_TEST_OUT) / "redteam-limits";
    fs::create_directories(dir);
    const fs::path err = dir / "stderr.txt";
    for (const char* flag : {"--max-memory 1", "--max-memory lots", "--max-memory 1M", "--max-step-seconds 0"}) {
        const std::string cmd = std::string(TEARABLES_CLI) + " run " + (kCorpus / "cloth-500x500.json").string() + " --quiet --out " +
                                (dir / "out").string() + " " + flag + " 2>" + err.string() + " >/dev/null";
        const int raw = std::system(cmd.c_str());
        ASSERT_TRUE(WIFEXITED(raw));
        EXPECT_EQ(WEXITSTATUS(raw), 2) << flag;
        const std::string said = slurp(err);
        const std::string named = std::string(flag) == "--max-memory 1M" ? "cloths[0].resolution" : std::string(flag).substr(0, std::string(flag).find(' '));
        EXPECT_NE(said.find(named), std::string::npos) << flag << ": " << said;
        EXPECT_FALSE(fs::exists(dir / "out" / "trace.jsonl")) << flag;
    }
}
