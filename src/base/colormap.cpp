// The tension colour map. Control points are sampled from matplotlib's "plasma" (CC0), whose
// lightness rises monotonically; between them we interpolate linearly in RGB, which keeps the
// luminance monotonic because it is linear in RGB and rises at every control point.
#include "tearables/colormap.hpp"

#include <algorithm>
#include <cmath>

namespace tearables {

namespace {

constexpr std::array<Rgb, 6> kPlasma = {{
    {0.050f, 0.030f, 0.528f},
    {0.417f, 0.000f, 0.658f},
    {0.693f, 0.165f, 0.565f},
    {0.881f, 0.393f, 0.383f},
    {0.988f, 0.652f, 0.211f},
    {0.940f, 0.975f, 0.131f},
}};

}  // namespace

Rgb tensionColor(double u) {
    if (!std::isfinite(u)) u = 0.0;
    u = std::clamp(u, 0.0, 1.0);
    const double x = u * static_cast<double>(kPlasma.size() - 1);
    const std::size_t i = std::min<std::size_t>(static_cast<std::size_t>(x), kPlasma.size() - 2);
    const float f = static_cast<float>(x - static_cast<double>(i));
    const Rgb& a = kPlasma[i];
    const Rgb& b = kPlasma[i + 1];
    return {a.r + f * (b.r - a.r), a.g + f * (b.g - a.g), a.b + f * (b.b - a.b)};
}

double luminance(const Rgb& c) { return 0.2126 * c.r + 0.7152 * c.g + 0.0722 * c.b; }

double loadFraction(double tension, double rupture_stress, double radius) {
    const double rupture_tension = rupture_stress * M_PI * radius * radius;
    if (!std::isfinite(tension) || !std::isfinite(rupture_tension) || !(rupture_tension > 0.0)) return 0.0;
    return std::clamp(tension / rupture_tension, 0.0, 1.0);
}

}  // namespace tearables
