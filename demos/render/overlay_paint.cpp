// The overlay painted into a headless frame on the CPU, after the 3-D picture is read back:
// flat rectangles, and text rasterised by FreeType from DejaVu Sans (fonts-dejavu-core).
#include "render/overlay.hpp"

#include <ft2build.h>
#include FT_FREETYPE_H

#include <algorithm>
#include <cmath>
#include <memory>
#include <stdexcept>

namespace tearables::render {

namespace {

constexpr const char* kFontPath = "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf";

/// FreeType's library and the font face at the overlay's text height, loaded once per thread.
class Font {
public:
    Font() {
        if (FT_Init_FreeType(&library_) != 0) throw std::runtime_error("FreeType could not be initialised");
        if (FT_New_Face(library_, kFontPath, 0, &face_) != 0) {
            FT_Done_FreeType(library_);
            throw std::runtime_error(std::string("the overlay's font ") + kFontPath +
                                     " could not be loaded: sudo apt-get install fonts-dejavu-core");
        }
        setHeight(kTextHeight);
    }
    /// Sets the glyphs' size for text `height` pixels high (line height; the em is 2 less).
    void setHeight(int height) {
        if (height != height_) FT_Set_Pixel_Sizes(face_, 0, static_cast<FT_UInt>(std::max(height - 2, 4)));
        height_ = height;
    }
    ~Font() {
        FT_Done_Face(face_);
        FT_Done_FreeType(library_);
    }
    Font(const Font&) = delete;
    Font& operator=(const Font&) = delete;
    FT_Face face() const { return face_; }

private:
    FT_Library library_ = nullptr;
    FT_Face face_ = nullptr;
    int height_ = 0;
};

Font& font() {
    thread_local Font f;
    return f;
}

/// Blends `c` (0-255 per channel) over pixel (x, y) with opacity a in [0, 1]; outside: nothing.
void blend(Image& im, int x, int y, const std::array<float, 3>& c, float a) {
    if (x < 0 || y < 0 || x >= im.width || y >= im.height || !(a > 0.0f)) return;
    const std::size_t i = (static_cast<std::size_t>(y) * static_cast<std::size_t>(im.width) + static_cast<std::size_t>(x)) * 3;
    for (int ch = 0; ch < 3; ++ch)
        im.rgb[i + ch] = static_cast<std::uint8_t>(std::lround(im.rgb[i + ch] * (1.0f - a) + c[ch] * a));
}

/// Fills the pixels whose centres lie in [x0, x1) x [y0, y1).
void fillRect(Image& im, float x0, float y0, float x1, float y1, const std::array<float, 3>& c, float a = 1.0f) {
    for (int y = static_cast<int>(std::ceil(y0 - 0.5f)); y + 0.5f < y1; ++y)
        for (int x = static_cast<int>(std::ceil(x0 - 0.5f)); x + 0.5f < x1; ++x) blend(im, x, y, c, a);
}

/// The width of `text` in pixels (its advances).
float textWidth(const std::string& text) {
    FT_Face face = font().face();
    float w = 0.0f;
    for (unsigned char ch : text)
        if (FT_Load_Char(face, ch, FT_LOAD_DEFAULT) == 0) w += static_cast<float>(face->glyph->advance.x) / 64.0f;
    return w;
}

/// Draws `text` (ASCII) with its left end at x and its middle at y, in colour c.
void drawText(Image& im, const std::string& text, float x, float middle, const std::array<float, 3>& c) {
    FT_Face face = font().face();
    const float ascender = static_cast<float>(face->size->metrics.ascender) / 64.0f;
    const float descender = static_cast<float>(face->size->metrics.descender) / 64.0f;  // negative
    const int baseline = static_cast<int>(std::lround(middle + 0.5f * (ascender + descender)));
    float pen = x;
    for (unsigned char ch : text) {
        if (FT_Load_Char(face, ch, FT_LOAD_RENDER) != 0) continue;
        const FT_GlyphSlot g = face->glyph;
        const FT_Bitmap& b = g->bitmap;
        const int left = static_cast<int>(std::lround(pen)) + g->bitmap_left, top = baseline - g->bitmap_top;
        for (unsigned row = 0; row < b.rows; ++row)
            for (unsigned col = 0; col < b.width; ++col)
                blend(im, left + static_cast<int>(col), top + static_cast<int>(row), c,
                      b.buffer[row * static_cast<unsigned>(b.pitch) + col] / 255.0f);
        pen += static_cast<float>(g->advance.x) / 64.0f;
    }
}

}  // namespace

void paintOverlay(Image& image, const scene::Scene& scene, double time, long long step) {
    if (image.width < kMinOverlayWidth || image.height < kMinOverlayHeight) return;
    const std::array<float, 3> ink{30.0f, 30.0f, 30.0f}, paper{255.0f, 255.0f, 255.0f};
    // The time stamp on a light box (the sky and the ground are both light; the box keeps
    // the text readable over a dark body).
    const float scale = overlayScale(image.width, image.height);
    const float text_height = static_cast<float>(kTextHeight) * scale;
    font().setHeight(static_cast<int>(std::lround(text_height)));
    const StampBox box = StampBox::at(scale);
    const std::string stamp = timeStamp(time, step);
    fillRect(image, box.x0, box.y0, box.x0 + textWidth(stamp) + 12.0f * scale, box.y0 + text_height + 6.0f * scale, paper, 0.75f);
    drawText(image, stamp, box.x0 + 6.0f * scale, box.y0 + 3.0f * scale + 0.5f * text_height, ink);
    for (const ColorBar& bar : colorBars(scene, image.width, image.height, scale)) {
        // A light box under the bar and its labels, as under the stamp.
        float box_left = bar.x0 - 1.0f, box_top = bar.y0 - 1.0f, box_bottom = bar.y1 + 1.0f;
        for (const TextPlacement& t : bar.labels) {
            box_left = std::min(box_left, t.right - textWidth(t.text));
            box_top = std::min(box_top, t.middle - 0.5f * text_height);
            box_bottom = std::max(box_bottom, t.middle + 0.5f * text_height);
        }
        const float pad = 4.0f * scale;
        fillRect(image, box_left - pad, box_top - pad, bar.x1 + 1.0f + pad, box_bottom + pad, paper, 0.75f);
        for (int k = 0; k < ColorBar::kBands; ++k) {
            const auto [top, bottom] = bar.bandRows(k);
            const Rgb c = ColorBar::bandColor(k);
            fillRect(image, bar.x0, top, bar.x1, bottom, {255.0f * c.r, 255.0f * c.g, 255.0f * c.b});
        }
        const std::array<float, 3> frame{60.0f, 60.0f, 60.0f};
        fillRect(image, bar.x0 - 1, bar.y0 - 1, bar.x1 + 1, bar.y0, frame);
        fillRect(image, bar.x0 - 1, bar.y1, bar.x1 + 1, bar.y1 + 1, frame);
        fillRect(image, bar.x0 - 1, bar.y0, bar.x0, bar.y1, frame);
        fillRect(image, bar.x1, bar.y0, bar.x1 + 1, bar.y1, frame);
        for (const TextPlacement& t : bar.labels) drawText(image, t.text, t.right - textWidth(t.text), t.middle, ink);
    }
}

}  // namespace tearables::render
