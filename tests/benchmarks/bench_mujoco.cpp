// MuJoCo as the exact reference (issue 9), in the same run as tearables: the rope of
// bench_bullet.cpp (segments of 1 cm and 1 g, hanging from a fixed point with a tip mass
// 10x the rope's, dt = 0.01 s, laid out horizontally and swinging down) as a chain of
// bodies on ball joints (timed hanging at rest: it diverges swinging, see
// BM_Rope_MuJoCo). The chain is exactly inextensible (its joints are the
// coordinates) and its constraint forces are exact, but each step factorises the joint
// space mass matrix, dense along a chain: O(N^3) per step. Sizes up to 200 links (746
// takes about a second per step). Reported per step: time, and the elongation after 2 s
// (counter "stretch"; zero up to rounding for MuJoCo by construction).
//
// BM_Rope_Tearables is the same rope in tearables (core and Bullet plugin, no bodies
// other than the tip), at the same sizes, so the ratio is read off one table.
// Run: build/tests/benchmarks/tearables_bench --benchmark_filter='Rope_'
#include "bench_rope.hpp"

#include <btBulletDynamicsCommon.h>
#include <benchmark/benchmark.h>
#include <mujoco/mujoco.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace {

using namespace tearables::bench;

/// Links per MJCF file: the XML reader refuses elements nested deeper than about 100, so
/// the chain is written as files of 40 nested bodies, each including the next at its
/// innermost body (MuJoCo splices an included file's elements in place).
constexpr int kLinksPerFile = 40;

/// Writes the chain as MJCF files in `dir` and returns the main one: N nested bodies, each
/// a capsule of one segment with a ball joint at its start; the tip mass is a small
/// sphere at the far end of the last.
/// `gravity` along x makes it hang straight at rest; along -y it swings down.
std::filesystem::path writeChain(int segments, const std::filesystem::path& dir, const char* gravity) {
    const double tip = 10.0 * segments * kSegmentMass;
    const int files = (segments + kLinksPerFile - 1) / kLinksPerFile;
    auto name = [&](int f) { return dir / ("chain" + std::to_string(f) + ".xml"); };
    for (int f = 0; f < files; ++f) {
        std::ofstream xml(name(f));
        xml << "<mujoco>";
        if (f == 0)
            xml << "<option timestep=\"" << kDt << "\" gravity=\"" << gravity << "\" integrator=\"Euler\"/>"
                << "<default><geom contype=\"0\" conaffinity=\"0\"/></default><worldbody>";
        const int lo = f * kLinksPerFile, hi = std::min(segments, lo + kLinksPerFile);
        for (int i = lo; i < hi; ++i) {
            xml << "<body pos=\"" << (i == 0 ? 0.0 : kSegmentLength) << " 0 0\"><joint type=\"ball\"/>"
                << "<geom type=\"capsule\" fromto=\"0 0 0 " << kSegmentLength << " 0 0\" size=\"0.004\" mass=\"" << kSegmentMass
                << "\"/>";
            if (i == segments - 1)
                xml << "<geom type=\"sphere\" pos=\"" << kSegmentLength << " 0 0\" size=\"0.004\" mass=\"" << tip << "\"/>";
        }
        if (f + 1 < files) xml << "<include file=\"" << name(f + 1).filename().string() << "\"/>";
        for (int i = lo; i < hi; ++i) xml << "</body>";
        xml << (f == 0 ? "</worldbody></mujoco>" : "</mujoco>");
    }
    return name(0);
}

struct MjRope {
    mjModel* model = nullptr;
    mjData* data = nullptr;
    MjRope(int segments, const char* gravity) {
        const std::filesystem::path dir =
            std::filesystem::temp_directory_path() / ("tearables_bench_chain_" + std::to_string(segments));
        std::filesystem::create_directories(dir);
        char error[1000] = "";
        model = mj_loadXML(writeChain(segments, dir, gravity).string().c_str(), nullptr, error, sizeof error);
        std::filesystem::remove_all(dir);
        if (!model) throw std::runtime_error(std::string("MuJoCo: ") + error);
        data = mj_makeData(model);
    }
    ~MjRope() {
        mj_deleteData(data);
        mj_deleteModel(model);
    }
    MjRope(const MjRope&) = delete;
    MjRope& operator=(const MjRope&) = delete;
    /// Length of the chain through its joints and the tip, over its rest length, minus one.
    double stretch(int segments) const {
        double length = 0.0;
        for (int b = 2; b <= segments; ++b) {  // body 0 is the world, 1 the first link
            const mjtNum* p = data->xpos + 3 * b;
            const mjtNum* q = data->xpos + 3 * (b - 1);
            length += std::sqrt((p[0] - q[0]) * (p[0] - q[0]) + (p[1] - q[1]) * (p[1] - q[1]) + (p[2] - q[2]) * (p[2] - q[2]));
        }
        return (length + kSegmentLength) / (segments * kSegmentLength) - 1.0;
    }
    /// MuJoCo reset the state after a non-finite acceleration (its warning counter).
    bool diverged() const { return data->warning[mjWARN_BADQACC].number > 0; }
};

void BM_Rope_MuJoCo(benchmark::State& state) {
    const int segments = static_cast<int>(state.range(0));
    // The swing of the other ropes: MuJoCo's step diverges (a non-finite acceleration,
    // after which it resets the state) within the first second at dt = 0.01, whatever
    // the integrator (Euler, RK4, implicit; rotor inertia up to 1e-4 kg m^2 per joint
    // only delays it). Counter "diverged_s": when.
    double diverged = 0.0;
    {
        MjRope swinging(segments, "0 -9.81 0");
        for (int i = 0; i < kSettle && diverged == 0.0; ++i) {
            mj_step(swinging.model, swinging.data);  // (it resets its clock when it diverges)
            if (swinging.diverged()) diverged = (i + 1) * kDt;
        }
    }
    // Timed hanging straight at rest, where it stays exact: a step costs the same (the
    // dense joint-space factorisation does not depend on the motion).
    MjRope rope(segments, "9.81 0 0");
    for (int i = 0; i < kSettle; ++i) mj_step(rope.model, rope.data);
    for (auto _ : state) mj_step(rope.model, rope.data);
    state.counters["stretch"] = rope.stretch(segments);
    state.counters["diverged_s"] = diverged;
    if (rope.diverged()) state.SkipWithError("MuJoCo diverged hanging at rest");
}
BENCHMARK(BM_Rope_MuJoCo)->Arg(100)->Arg(150)->Arg(200)->Unit(benchmark::kMicrosecond)->Iterations(100);

void BM_Rope_Tearables(benchmark::State& state) { timeTearablesRope(state, static_cast<int>(state.range(0))); }
BENCHMARK(BM_Rope_Tearables)->Arg(100)->Arg(150)->Arg(200)->Arg(746)->Unit(benchmark::kMicrosecond)->Iterations(100);

}  // namespace
