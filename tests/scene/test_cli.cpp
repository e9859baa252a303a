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
