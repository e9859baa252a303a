// What is drawn over a scene's picture, in pixels: the colour bars (tension of strings,
// damage of cloths and paper sheets) and the time stamp. The layout is computed here once; the viewer draws it with Dear ImGui
// (demos/viewer/viewer.cpp), headless frames with paintOverlay (overlay_paint.cpp).
#pragma once

#include "render/renderer.hpp"
#include "render/scene_painter.hpp"
#include "tearables/scene.hpp"

#include <string>
#include <utility>
#include <vector>

namespace tearables::render {

/// The rupture tensions (N) of the scene's strings, smallest and largest (0, 0 when it has
/// none): the colours of ropes are each one's load / its own rupture tension.
std::pair<double, double> ruptureTensions(const scene::Scene& scene);

/// A line of text placed in the picture: right-aligned at x = `right` (pixels from the left),
/// its middle at y = `middle` (pixels from the top).
struct TextPlacement {
    std::string text;      ///< ASCII
    float right = 0.0f;    ///< x of the text's right end, pixels from the left
    float middle = 0.0f;   ///< y of the text's middle, pixels from the top
};

/// What a colour bar explains.
enum class BarKind {
    Tension,  ///< strings: load / rupture load
    Twist,    ///< strings: torsional strain / torsional rupture strain (RopeColors::Twist)
    Damage,   ///< cloths and paper sheets: the damaged share around each vertex (clothDamage, paperDamage)
};

/// A colour bar: from the bottom (tensionColor(0): slack, or intact) to the top
/// (tensionColor(1): tears, or all damaged), in kBands flat bands.
struct ColorBar {
    BarKind kind = BarKind::Tension;                   ///< what the colours mean
    static constexpr int kBands = 64;                  ///< flat bands from load 0 to load 1
    float x0 = 0.0f, y0 = 0.0f, x1 = 0.0f, y1 = 0.0f;  ///< the bar's rectangle, pixels from the top-left
    std::vector<TextPlacement> labels;                 ///< ticks left of the bar, bottom to top
    /// Band k's rows [top, bottom) (k = 0 at the bottom) and colour, tensionColor((k + 0.5) / kBands).
    std::pair<float, float> bandRows(int k) const;
    static Rgb bandColor(int k);
};

/// The colour bars of a picture width x height pixels for `scene`, right to left: tension at
/// the right edge where the scene has strings, damage where it has cloths or paper sheets
/// (left of the tension bar when both). Tension ticks are in newtons when every rope tears at
/// the same tension, otherwise a share of each one's own rupture tension with their range
/// under the bar; damage ticks are the share 0..1 with what counts as damage under the bar.
/// `labels` holds the title above the bar first. Lengths are `scale` times those of a
/// 640x360 picture (1 in the viewer's window, whose text does not scale; overlayScale for
/// headless frames); text is kTextHeight * scale pixels high.
/// With RopeColors::Twist the strings' bar is the twist's: torsional strain over the
/// torsional rupture strain, 0..1.
std::vector<ColorBar> colorBars(const scene::Scene& scene, int width, int height, float scale = 1.0f,
                                RopeColors colors = RopeColors::Load);

/// The overlay's scale for a headless frame: its height over 360 pixels (the overlay keeps
/// its share of the picture), but at least kMinOverlayScale so that the text stays legible.
float overlayScale(int width, int height);
constexpr float kMinOverlayScale = 0.7f;  ///< text 9 pixels high
constexpr int kTextHeight = 13;           ///< the overlay's text height at scale 1, pixels

/// True when the scene has strings (whose colours the tension bar explains).
bool showsTension(const scene::Scene& scene);
/// True when the scene has cloths or paper sheets (whose colours the damage bar explains).
bool showsDamage(const scene::Scene& scene);

/// The time stamp's text, "t = 1.250 s   step 125".
std::string timeStamp(double time, long long step);

/// The time stamp's box at the picture's top-left corner, pixels from the top-left: the text
/// starts at (x0 + 6 scale, y0 + 3 scale) and is kTextHeight * scale high.
struct StampBox {
    float x0 = 8.0f;     ///< the box's left edge, pixels
    float y0 = 8.0f;     ///< the box's top edge, pixels
    float scale = 1.0f;  ///< as colorBars' scale
    /// The box at a scale (its corner 8 * scale pixels from the picture's).
    static StampBox at(float scale) { return {8.0f * scale, 8.0f * scale, scale}; }
};

/// Paints the time stamp and the scene's colour bars (colorBars) at overlayScale into a headless
/// frame (with FreeType and the DejaVu Sans font of Debian's fonts-dejavu-core). Pictures
/// smaller than kMinOverlayWidth x kMinOverlayHeight are left as they are (no room).
/// Throws std::runtime_error when the font cannot be loaded, saying how to install it.
void paintOverlay(Image& image, const scene::Scene& scene, double time, long long step);
constexpr int kMinOverlayWidth = 240;   ///< pixels; narrower pictures get no overlay
constexpr int kMinOverlayHeight = 135;  ///< pixels; lower pictures get no overlay

}  // namespace tearables::render
