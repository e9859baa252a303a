// The `tearables` command line, run as a user runs it: exit status, messages with JSON
// paths, outputs, determinism.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <sys/wait.h>
#include <unistd.h>

namespace {

namespace fs = std::filesystem;

struct Result {
    int status = -1;
    std::string out;
    std::string err;
};

std::string slurp(const fs::path& p) {
    std::ifstream in(p);
    std::stringstream s;
    s << in.rdbuf();
    return s.str();
}

/// Runs the CLI with `args`, capturing stdout and stderr.
Result cli(const std::string& args) {
    const fs::path dir = fs::path(TEARABLES_TEST_OUT) / "cli";
    fs::create_directories(dir);
    // Per process: CTest runs the tests of this file in parallel.
    const std::string tag = std::to_string(::getpid());
    const fs::path out = dir / ("stdout-" + tag + ".txt"), err = dir / ("stderr-" + tag + ".txt");
    const std::string cmd = std::string(TEARABLES_CLI) + " " + args + " >" + out.string() + " 2>" + err.string();
    const int raw = std::system(cmd.c_str());
    Result r;
    r.status = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
    r.out = slurp(out);
    r.err = slurp(err);
    return r;
}

fs::path writeScene(const std::string& name, const std::string& text) {
    const fs::path dir = fs::path(TEARABLES_TEST_OUT) / "cli-scenes";
    fs::create_directories(dir);
    const fs::path p = dir / (name + ".json");
    std::ofstream(p) << text;
    return p;
}

const char* kGoodRope = R"({
  "dt": 0.01, "steps": 50,
  "bodies": [ {"name": "crate", "shape": {"box": [0.1, 0.1, 0.1]}, "mass": 2, "position": [0, 0.9, 0]} ],
  "strings": [ {"name": "rope", "from": [0, 2, 0], "to": [0, 1, 0], "segments": 10,
                "attachments": [ {"particle": 0, "world": [0, 2, 0]},
                                 {"particle": -1, "body": "crate", "local": [0, 0.1, 0]} ] } ],
  "drivers": [ {"type": "force", "target": "rope", "particle": 5, "value": [1, 0, 0], "until": 0.2} ]
})";

}  // namespace

TEST(Cli, RunsASceneAndWritesItsOutputs) {
    const fs::path scene = writeScene("good", kGoodRope);
    const fs::path out = fs::path(TEARABLES_TEST_OUT) / "cli-good";
    fs::remove_all(out);
    const Result r = cli("run " + scene.string() + " --out " + out.string() + " --every 10 --quiet");
    ASSERT_EQ(r.status, 0) << r.err;
    // trace: frames at steps 0, 10, ..., 50 with every particle and segment.
    std::ifstream trace(out / "trace.jsonl");
    std::string line;
    int frames = 0;
    while (std::getline(trace, line)) {
        const auto f = nlohmann::json::parse(line);
        EXPECT_EQ(f["step"].get<int>(), 10 * frames);
        EXPECT_EQ(f["strings"]["rope"]["x"].size(), 11u);
        EXPECT_EQ(f["strings"]["rope"]["tension"].size(), 10u);
        EXPECT_EQ(f["bodies"]["crate"]["p"].size(), 3u);
        ++frames;
    }
    EXPECT_EQ(frames, 6);
    const auto summary = nlohmann::json::parse(slurp(out / "summary.json"));
    EXPECT_EQ(summary["steps"].get<int>(), 50);
    EXPECT_NEAR(summary["simulated_seconds"].get<double>(), 0.5, 1e-12);
    EXPECT_TRUE(summary["stage_seconds"].contains("strain_limit"));
    EXPECT_EQ(summary["digest"].get<std::string>().size(), 16u);
    // The crate hangs on the rope: one island a step, each solved to tolerance (one
    // rope and one body, no contact: nothing for the Newton solve to struggle with).
    const auto& islands = summary["islands"];
    EXPECT_EQ(islands["solves"].get<int>(), 50);
    EXPECT_GE(islands["iterations"].get<int>(), 50);
    EXPECT_GE(islands["most_iterations"].get<int>(), 1);
    EXPECT_EQ(islands["unconverged"].get<int>(), 0);
    EXPECT_TRUE(fs::exists(out / "events.jsonl"));
}

TEST(Cli, SameSceneSameDigest) {
    const fs::path scene = writeScene("digest", kGoodRope);
    const fs::path a = fs::path(TEARABLES_TEST_OUT) / "cli-digest-a", b = fs::path(TEARABLES_TEST_OUT) / "cli-digest-b";
    ASSERT_EQ(cli("run " + scene.string() + " --out " + a.string() + " --quiet").status, 0);
    ASSERT_EQ(cli("run " + scene.string() + " --out " + b.string() + " --quiet").status, 0);
    EXPECT_EQ(nlohmann::json::parse(slurp(a / "summary.json"))["digest"],
              nlohmann::json::parse(slurp(b / "summary.json"))["digest"]);
    EXPECT_EQ(slurp(a / "trace.jsonl"), slurp(b / "trace.jsonl"));
}

TEST(Cli, StepsOverrideAndBuiltinScenes) {
    const Result list = cli("list");
    ASSERT_EQ(list.status, 0);
    EXPECT_NE(list.out.find("swing"), std::string::npos);
    const fs::path out = fs::path(TEARABLES_TEST_OUT) / "cli-builtin";
    const Result r = cli("run swing --steps 20 --out " + out.string());
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_NE(r.out.find(out.string()), std::string::npos);  // says where the output went
    EXPECT_EQ(nlohmann::json::parse(slurp(out / "summary.json"))["steps"].get<int>(), 20);
}

// Every scene error exits 2 with the field's JSON path in the message, and simulates nothing.
TEST(Cli, InvalidScenesExitTwoNamingTheField) {
    struct Case {
        const char* name;
        std::string text;
        const char* path;
    };
    const std::string rope = R"("strings": [ {"name": "rope", "from": [0, 2, 0], "to": [0, 1, 0], "segments": 10)";
    const std::vector<Case> cases = {
        {"unknown-field", R"({"stepz": 10})", "stepz"},
        {"wrong-type", "{" + rope + R"(, "radius": "thin"} ]})", "strings[0].radius"},
        {"negative-mass", R"({"bodies": [ {"name": "b", "shape": {"sphere": 0.1}, "mass": -1} ]})", "bodies[0].mass"},
        {"negative-radius", "{" + rope + R"(, "radius": -0.002} ]})", "strings[0].radius"},
        {"huge-number", R"({"dt": 1e999})", "dt"},
        {"zero-length", R"({"strings": [ {"name": "r", "points": [[0,0,0],[0,1,0],[0,1,0]]} ]})", "strings[0].points[2]"},
        {"rupture-below-yield",
         "{" + rope + R"(, "material": {"tensile": {"yield": 5e7, "rupture": 4e7}}} ]})",
         "strings[0].material.tensile.rupture"},
        {"missing-body", "{" + rope + R"(, "attachments": [ {"particle": 0, "body": "beam"} ]} ]})",
         "strings[0].attachments[0].body"},
        {"particle-out-of-range", "{" + rope + R"(, "attachments": [ {"particle": 11, "world": [0,0,0]} ]} ]})",
         "strings[0].attachments[0].particle"},
        {"driver-particle", "{" + rope + R"(} ], "drivers": [ {"type": "force", "target": "rope", "particle": 40, "value": [0,1,0]} ]})",
         "drivers[0].particle"},
        {"twist-unclamped-end", "{" + rope + R"(, "attachments": [ {"particle": 0, "world": [0,2,0]} ]} ], "drivers": [ {"type": "twist", "target": "rope", "end": -1, "rate": 1} ]})",
         "drivers[0].end"},
    };
    for (const Case& c : cases) {
        const fs::path scene = writeScene(c.name, c.text);
        const fs::path out = fs::path(TEARABLES_TEST_OUT) / (std::string("cli-bad-") + c.name);
        fs::remove_all(out);
        const Result r = cli("run " + scene.string() + " --out " + out.string() + " --quiet");
        EXPECT_EQ(r.status, 2) << c.name << ": " << r.err;
        EXPECT_NE(r.err.find(std::string(c.path) + ":"), std::string::npos) << c.name << ": " << r.err;
        EXPECT_FALSE(fs::exists(out / "summary.json")) << c.name;
    }
}

TEST(Cli, BadArgumentsExitTwo) {
    EXPECT_EQ(cli("run").status, 2);
    EXPECT_EQ(cli("run no-such-scene-anywhere").status, 2);
    EXPECT_EQ(cli("frobnicate").status, 2);
    EXPECT_EQ(cli("run swing --steps -3").status, 2);
}

// The shoot driver: each shot goes to the nearest thing on its ray. A rope hanging in
// front of a crate takes the first shot (the crate is not pushed); a ray that passes
// everything misses; a ray off the crate's centre line (no rope in the way) pushes and
// spins it. Every shot is an event, counted in the summary.
TEST(Cli, ShootHitsTheNearestThingOnItsRay) {
    const fs::path scene = writeScene("shoot", R"({
      "dt": 0.01, "steps": 40, "gravity": [0, 0, 0],
      "bodies": [ {"name": "crate", "shape": {"box": [0.1, 0.1, 0.1]}, "mass": 1, "position": [0, 1, 0]} ],
      "strings": [ {"name": "rope", "from": [0, 1.5, 0.3], "to": [0, 0.5, 0.3], "segments": 10,
                    "attachments": [ {"particle": 0, "world": [0, 1.5, 0.3]}, {"particle": -1, "world": [0, 0.5, 0.3]} ]} ],
      "drivers": [
        {"type": "shoot", "ray": {"from": [0, 1, 1], "to": [0, 1, -1]}, "impulse": 0.01, "times": [0.05]},
        {"type": "shoot", "ray": {"from": [0.5, 1, 1], "to": [0.5, 1, -1]}, "impulse": 0.01, "times": [0.1]},
        {"type": "shoot", "ray": {"from": [0.06, 0.9, 1], "to": [0.06, 0.9, -1]}, "impulse": 0.5, "times": [0.2]} ]})");
    const fs::path out = fs::path(TEARABLES_TEST_OUT) / "cli-shoot";
    fs::remove_all(out);
    const Result r = cli("run " + scene.string() + " --quiet --out " + out.string());
    ASSERT_EQ(r.status, 0) << r.err;
    std::vector<nlohmann::json> shots;
    std::istringstream events(slurp(out / "events.jsonl"));
    std::string line;
    while (std::getline(events, line)) {
        const nlohmann::json e = nlohmann::json::parse(line);
        if (e["type"] == "shot") shots.push_back(e);
    }
    ASSERT_EQ(shots.size(), 3u);
    EXPECT_EQ(shots[0]["object"], "rope");
    EXPECT_NEAR(shots[0]["point"][2].get<double>(), 0.3, 0.01);  // the rope's near side
    EXPECT_FALSE(shots[1]["hit"].get<bool>());
    EXPECT_FALSE(shots[1].contains("object"));
    EXPECT_EQ(shots[2]["object"], "crate");
    // The crate's front face, within Bullet's ray-convex tolerance (its GJK cast stops within mm).
    EXPECT_NEAR(shots[2]["point"][2].get<double>(), 0.1, 0.01);
    EXPECT_EQ(nlohmann::json::parse(slurp(out / "summary.json"))["events"]["shot"], 3);
    // The crate: untouched by the first shot (the rope took it), pushed along -z by the
    // third (0.5 N s on 1 kg: 0.5 m/s) and turned about y (the hit is 6 cm off its centre).
    std::istringstream trace(slurp(out / "trace.jsonl"));
    nlohmann::json before_third, last;
    while (std::getline(trace, line)) {
        last = nlohmann::json::parse(line);
        if (last["t"].get<double>() <= 0.2 + 1e-9) before_third = last;
    }
    EXPECT_NEAR(before_third["bodies"]["crate"]["v"][2].get<double>(), 0.0, 1e-6);
    EXPECT_NEAR(last["bodies"]["crate"]["v"][2].get<double>(), -0.5, 0.05);
    EXPECT_GT(std::abs(last["bodies"]["crate"]["q"][1].get<double>()), 0.05);  // turned about y
}
