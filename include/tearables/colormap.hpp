// tearables: the tension colour map shared by the debug drawing (plugin/) and the offscreen
// renderer (demos/render/). Pure arithmetic, no graphics library.
#pragma once

#include <array>

namespace tearables {

/// An RGB colour, each channel in [0, 1].
struct Rgb {
    float r = 0.0f;  ///< red, [0, 1]
    float g = 0.0f;  ///< green, [0, 1]
    float b = 0.0f;  ///< blue, [0, 1]
};

/// The colour of a load fraction `u` = tension / rupture tension: a "plasma"-like ramp from
/// deep blue (slack, u <= 0) through magenta and orange to yellow (about to tear, u >= 1).
/// Its luminance rises strictly with u, so the order of tensions survives a grey-scale
/// print. Non-finite u gives the u = 0 colour.
Rgb tensionColor(double u);

/// Relative luminance of a colour (Rec. 709 weights), [0, 1].
double luminance(const Rgb& c);

/// The load fraction of a segment: tension / (rupture stress * pi r^2), clamped to [0, 1];
/// 0 for a non-positive rupture tension or non-finite input.
double loadFraction(double tension, double rupture_stress, double radius);

}  // namespace tearables
