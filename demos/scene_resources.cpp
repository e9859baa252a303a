// A scene's memory and per-step time, estimated from its counts before anything is built,
// and the limits a run refuses to pass (RunOptions::limits, the CLI's --max-memory and
// --max-step-seconds).
//
// Each object costs a fixed amount per item, with these items:
// - a string: its segments, plus the segment pairs its self-collision search visits. A
//   segment's capsule reaches the segments within 2 r of it along the chain, about
//   2 r / l of them (r the radius, l the segment's length), and the search visits each of
//   those pairs (the neighbours it then skips, string_pairs.cpp, included), so the pairs
//   are sum over segments of 2 r / l_j;
// - a cloth: its vertices for memory; for time V^1.5, the growth of a sparse Cholesky
//   factorisation of a 2-D grid's normal equations under nested dissection (George, "Nested
//   dissection of a regular finite element mesh", SIAM J. Numer. Anal. 10, 1973), which its
//   yarns' least-squares tension solve is;
// - a paper sheet: its vertices (Jacobi sweeps or conjugate gradients: linear per sweep).
// The per-item constants are measured (docs/resource-limits.md: how, and how far the
// estimate is from the measured runs).
#include "tearables/scene.hpp"

#include <cmath>
#include <cstdio>
#include <string>

namespace tearables::scene {

namespace {

constexpr double kProgramBytes = 1e8;           // the program, Bullet and the output buffers
constexpr double kStringSegmentBytes = 1.6e3;   // per segment (and its particle)
constexpr double kStringSegmentSeconds = 2.5e-7;
constexpr double kStringPairBytes = 125.0;      // per pair within reach along the chain
constexpr double kStringPairSeconds = 2.1e-7;
constexpr double kClothVertexBytes = 2.3e4;     // per vertex (yarns, the factorisation's fill)
constexpr double kClothSeconds = 5e-7;          // times V^1.5
constexpr double kPaperVertexBytes = 3e3;       // per vertex (springs, triangles, solver)
constexpr double kPaperVertexSeconds = 1.5e-6;

std::string bytesText(double b) {
    char buf[64];
    if (b >= 1e9)
        std::snprintf(buf, sizeof buf, "%.3g GB", b / 1e9);
    else
        std::snprintf(buf, sizeof buf, "%.3g MB", b / 1e6);
    return buf;
}

std::string secondsText(double s) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.3g s", s);
    return buf;
}

}  // namespace

ResourceEstimate estimateResources(const Scene& scene) {
    ResourceEstimate e;
    e.memory_bytes = kProgramBytes;
    auto add = [&e](const std::string& field, double bytes, double seconds) {
        e.memory_bytes += bytes;
        e.step_seconds += seconds;
        if (bytes > e.memory_share) {
            e.memory_share = bytes;
            e.memory_field = field;
        }
        if (seconds > e.step_share) {
            e.step_share = seconds;
            e.step_field = field;
        }
    };
    for (std::size_t i = 0; i < scene.strings.size(); ++i) {
        const String& s = scene.strings[i];
        const auto& x = s.desc.points;
        const double segments = x.size() > 1 ? static_cast<double>(x.size() - 1) : 0.0;
        double pairs = 0.0;
        for (std::size_t j = 0; j + 1 < x.size(); ++j) {
            const double l = (x[j + 1] - x[j]).norm();
            if (l > 0.0) pairs += 2.0 * s.desc.radius / l;
        }
        add("strings[" + std::to_string(i) + "]." + s.geometry_field, segments * kStringSegmentBytes + pairs * kStringPairBytes,
            segments * kStringSegmentSeconds + pairs * kStringPairSeconds);
    }
    for (std::size_t i = 0; i < scene.cloths.size(); ++i) {
        const double v = static_cast<double>(scene.cloths[i].desc.resolution[0]) * scene.cloths[i].desc.resolution[1];
        add("cloths[" + std::to_string(i) + "].resolution", v * kClothVertexBytes, kClothSeconds * std::pow(v, 1.5));
    }
    for (std::size_t i = 0; i < scene.papers.size(); ++i) {
        const PaperDesc& d = scene.papers[i].desc;
        const bool mesh = !d.vertices.empty();
        const double v = mesh ? static_cast<double>(d.vertices.size()) : static_cast<double>(d.resolution[0]) * d.resolution[1];
        add("papers[" + std::to_string(i) + (mesh ? "].vertices" : "].resolution"), v * kPaperVertexBytes, v * kPaperVertexSeconds);
    }
    return e;
}

void checkResources(const Scene& scene, const ResourceLimits& limits) {
    if (!(limits.memory_bytes > 0.0) || !std::isfinite(limits.memory_bytes))
        throw InvalidInput("--max-memory", "must be a positive number of bytes");
    if (!(limits.step_seconds > 0.0) || !std::isfinite(limits.step_seconds))
        throw InvalidInput("--max-step-seconds", "must be a positive number of seconds");
    const ResourceEstimate e = estimateResources(scene);
    if (e.memory_bytes > limits.memory_bytes)
        throw InvalidInput(e.memory_field.empty() ? "--max-memory" : e.memory_field,
                           "the scene needs an estimated " + bytesText(e.memory_bytes) + " of memory (this object " +
                               bytesText(e.memory_share) + "), more than the limit of " + bytesText(limits.memory_bytes) +
                               "; make it smaller, or raise the limit with --max-memory");
    if (e.step_seconds > limits.step_seconds)
        throw InvalidInput(e.step_field.empty() ? "--max-step-seconds" : e.step_field,
                           "a step of the scene takes an estimated " + secondsText(e.step_seconds) + " (this object " +
                               secondsText(e.step_share) + "), more than the limit of " + secondsText(limits.step_seconds) +
                               "; make it smaller, or raise the limit with --max-step-seconds");
}

}  // namespace tearables::scene
