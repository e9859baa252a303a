// Soak: the built-in cloth-tear scene's tear line is decided by its perforation, not by
// rounding. The scene runs 28 times with its cloth shifted by +-1e-9, 1e-8, 1e-7 and
// 1e-6 m along x, y and z, and with the pull's speed scaled by 1 +- 1e-9 and 1 +- 1e-6;
// every run must end with exactly the perforation's yarns broken (so one warp yarn per
// row, in the perforation's column, and no weft yarn). Differences that small change
// which of two equal tensions rounds higher, and nothing else.
//
// `soak_cloth_tear --no-perforation` runs the same perturbations on the scene without its
// weak yarns and reports the runs that end with one warp yarn per row within three
// neighbouring columns and no weft yarn (what DemoScenes.ClothTearRunsAcrossThePull asked
// before the perforation): a measurement of the tie, not a check; its exit status is 0.
#include "tearables/scene.hpp"

#include <cstdio>
#include <cstring>
#include <set>
#include <string>
#include <vector>

namespace {

namespace ts = tearables::scene;

struct Perturbation {
    std::string label;
    int axis = -1;        ///< the origin's coordinate shifted, or -1
    double shift = 0.0;   ///< m
    double speed = 1.0;   ///< factor on every move driver's velocity
};

std::vector<Perturbation> perturbations() {
    std::vector<Perturbation> out;
    for (int axis = 0; axis < 3; ++axis)
        for (double sign : {1.0, -1.0})
            for (double magnitude : {1e-9, 1e-8, 1e-7, 1e-6}) {
                char label[64];
                std::snprintf(label, sizeof label, "origin[%d] %+.0e m", axis, sign * magnitude);
                out.push_back({label, axis, sign * magnitude, 1.0});
            }
    for (double factor : {1.0 + 1e-9, 1.0 - 1e-9, 1.0 + 1e-6, 1.0 - 1e-6}) {
        char label[64];
        std::snprintf(label, sizeof label, "pull x %.9f", factor);
        out.push_back({label, -1, 0.0, factor});
    }
    return out;
}

/// The broken yarns at the end of a run.
std::vector<int> brokenAtTheEnd(const ts::Scene& scene) {
    std::vector<int> broken;
    ts::RunOptions options;  // no output directory: nothing is written
    options.every = static_cast<int>(scene.steps);
    options.on_frame = [&](const ts::FrameState& frame) {
        broken.clear();
        const tearables::ClothView& v = frame.cloths.at(0).view;
        for (std::size_t e = 0; e < v.edgeCount(); ++e)
            if ((*v.broken)[e]) broken.push_back(static_cast<int>(e));
    };
    ts::runScene(scene, options);
    return broken;
}

}  // namespace

int main(int argc, char** argv) {
    const bool without_perforation = argc > 1 && std::strcmp(argv[1], "--no-perforation") == 0;
    const ts::Scene base = ts::parseScene(*ts::builtinSceneText("cloth-tear"));
    if (base.cloths.size() != 1) {
        std::fprintf(stderr, "cloth-tear: expected one cloth\n");
        return 1;
    }
    const tearables::ClothDesc& desc = base.cloths[0].desc;
    const int nu = desc.resolution[0], nv = desc.resolution[1];
    const int warp_count = (nu - 1) * nv;
    std::set<int> perforation;
    for (const tearables::ClothWeakYarn& w : desc.weak_yarns)
        perforation.insert(w.kind == tearables::YarnKind::Warp ? w.j * (nu - 1) + w.i : warp_count + w.j * nu + w.i);
    if (!without_perforation && perforation.empty()) {
        std::fprintf(stderr, "cloth-tear has no weak yarns\n");
        return 1;
    }

    int passed = 0, runs = 0;
    for (const Perturbation& p : perturbations()) {
        ts::Scene scene = base;
        if (without_perforation) scene.cloths[0].desc.weak_yarns.clear();
        if (p.axis >= 0) (*scene.cloths[0].desc.corner)[p.axis] += p.shift;
        for (ts::Driver& d : scene.drivers)
            if (d.type == ts::Driver::Type::Move) d.velocity *= p.speed;
        const std::vector<int> broken = brokenAtTheEnd(scene);
        bool ok = true;
        std::set<int> rows, columns;
        std::string list;
        for (int e : broken) {
            list += " " + std::to_string(e);
            if (e >= warp_count) {
                ok = false;  // a weft yarn
                continue;
            }
            rows.insert(e / (nu - 1));
            columns.insert(e % (nu - 1));
        }
        if (without_perforation) {
            ok = ok && static_cast<int>(broken.size()) == nv && static_cast<int>(rows.size()) == nv &&
                 *columns.rbegin() - *columns.begin() <= 2;
        } else {
            ok = std::set<int>(broken.begin(), broken.end()) == perforation && broken.size() == perforation.size();
        }
        ++runs;
        passed += ok ? 1 : 0;
        std::printf("%-24s %s  broken:%s\n", p.label.c_str(), ok ? "pass" : "FAIL", list.c_str());
        std::fflush(stdout);
    }
    std::printf("%s: %d of %d runs %s\n", without_perforation ? "without the perforation" : "cloth-tear", passed, runs,
                without_perforation ? "cut the cloth across the pull in a band of 3 columns" : "tore exactly the perforation");
    return without_perforation || passed == runs ? 0 : 1;
}
