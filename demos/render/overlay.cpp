// The overlay's layout (render/overlay.hpp): pure arithmetic, shared by the viewer's window
// and the headless frames.
#include "render/overlay.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace tearables::render {

std::pair<double, double> ruptureTensions(const scene::Scene& s) {
    double lo = 1e300, hi = 0.0;
    const auto offer = [&](double stress, double radius) {
        const double f = stress * M_PI * radius * radius;
        lo = std::min(lo, f);
        hi = std::max(hi, f);
    };
    for (const scene::String& str : s.strings) offer(str.desc.material.tensile.rupture, str.desc.radius);
    return hi > 0.0 ? std::make_pair(lo, hi) : std::make_pair(0.0, 0.0);
}

bool showsTension(const scene::Scene& scene) { return !scene.strings.empty(); }
bool showsDamage(const scene::Scene& scene) { return !scene.cloths.empty() || !scene.papers.empty(); }

std::pair<float, float> ColorBar::bandRows(int k) const {
    return {y1 - (y1 - y0) * static_cast<float>(k + 1) / kBands, y1 - (y1 - y0) * static_cast<float>(k) / kBands};
}

Rgb ColorBar::bandColor(int k) { return tensionColor((k + 0.5) / kBands); }

float overlayScale(int /*width*/, int height) { return std::max(kMinOverlayScale, static_cast<float>(height) / 360.0f); }

std::vector<ColorBar> colorBars(const scene::Scene& scene, int width, int height, float scale, RopeColors colors) {
    std::vector<ColorBar> bars;
    const float h = static_cast<float>(height);
    // A window keeps 250 px below the bars for its panels; a small picture keeps 30.
    const float bottom = std::min(std::max(h - 250.0f * scale, 140.0f * scale), h - 30.0f * scale);
    // Each bar with its tick labels on its left takes this much of the width.
    const float pitch = 110.0f * scale;
    const auto place = [&](BarKind kind) {
        ColorBar bar;
        bar.kind = kind;
        bar.x1 = static_cast<float>(width) - 24.0f * scale - pitch * static_cast<float>(bars.size());
        bar.x0 = bar.x1 - 24.0f * scale;
        bar.y0 = 40.0f * scale;
        bar.y1 = bottom;
        return bar;
    };
    char text[96];
    if (showsTension(scene) && colors == RopeColors::Twist) {
        ColorBar bar = place(BarKind::Twist);
        bar.labels.push_back({"twist / rupture twist", bar.x1, bar.y0 - 16.0f * scale});
        for (int k = 0; k <= 4; ++k) {
            std::snprintf(text, sizeof text, "%.2f", k / 4.0);
            bar.labels.push_back({text, bar.x0 - 6.0f * scale, bar.y1 - (bar.y1 - bar.y0) * static_cast<float>(k) / 4.0f});
        }
        bar.labels.push_back({"r |dtheta| / l over rupture", bar.x1, bar.y1 + 14.0f * scale});
        bars.push_back(bar);
    } else if (showsTension(scene)) {
        ColorBar bar = place(BarKind::Tension);
        const auto [lo, hi] = ruptureTensions(scene);
        const bool newtons = hi > 0.0 && hi - lo <= 1e-9 * hi;
        bar.labels.push_back({newtons || hi == 0.0 ? "tension" : "tension / rupture", bar.x1, bar.y0 - 16.0f * scale});
        for (int k = 0; k <= 4; ++k) {
            if (newtons) std::snprintf(text, sizeof text, "%.4g N", hi * k / 4.0);
            else std::snprintf(text, sizeof text, "%.2f", k / 4.0);
            bar.labels.push_back({text, bar.x0 - 6.0f * scale, bar.y1 - (bar.y1 - bar.y0) * static_cast<float>(k) / 4.0f});
        }
        if (!newtons && hi > 0.0) {
            std::snprintf(text, sizeof text, "rupture %.4g-%.4g N", lo, hi);
            bar.labels.push_back({text, bar.x1, bar.y1 + 14.0f * scale});
        }
        bars.push_back(bar);
    }
    if (showsDamage(scene)) {
        ColorBar bar = place(BarKind::Damage);
        bar.labels.push_back({"damage", bar.x1, bar.y0 - 16.0f * scale});
        for (int k = 0; k <= 4; ++k) {
            std::snprintf(text, sizeof text, "%.2f", k / 4.0);
            bar.labels.push_back({text, bar.x0 - 6.0f * scale, bar.y1 - (bar.y1 - bar.y0) * static_cast<float>(k) / 4.0f});
        }
        const bool cloth = !scene.cloths.empty(), paper = !scene.papers.empty();
        bar.labels.push_back({cloth && paper ? "torn, creased, yielded" : cloth ? "torn; yield: plastic strain" : "faces creased or torn",
                              bar.x1, bar.y1 + 14.0f * scale});
        bars.push_back(bar);
    }
    return bars;
}

std::string timeStamp(double time, long long step) {
    char text[96];
    std::snprintf(text, sizeof text, "t = %.3f s   step %lld", time, step);
    return text;
}

}  // namespace tearables::render
