// tearables_render: offscreen pictures of scenes with Mesa's OSMesa (software OpenGL, no
// display needed) and legacy fixed-function GL. The core and the plugin know nothing of it;
// only the command line links it.
//
//   Renderer r(640, 360);
//   r.begin(View{eye, target, 40.0});
//   r.drawGround({0, 1, 0}, 0.0, centre, 5.0);
//   r.drawTube(points, radii, colours, broken);
//   writePng("frame.png", r.finish());
#pragma once

#include "tearables/colormap.hpp"
#include "tearables/types.hpp"

#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace tearables::render {

/// An 8-bit RGB image, rows from the top.
struct Image {
    int width = 0;
    int height = 0;
    std::vector<std::uint8_t> rgb;  ///< width * height * 3 bytes
    /// The pixel at column x, row y (from the top).
    std::array<std::uint8_t, 3> at(int x, int y) const {
        const std::size_t i = (static_cast<std::size_t>(y) * static_cast<std::size_t>(width) + static_cast<std::size_t>(x)) * 3;
        return {rgb[i], rgb[i + 1], rgb[i + 2]};
    }
};

/// Writes an image as PNG (libpng). Throws std::runtime_error naming the file on failure.
void writePng(const std::string& path, const Image& image);
/// Reads a PNG as 8-bit RGB (libpng). Throws std::runtime_error naming the file on failure.
Image readPng(const std::string& path);

/// A pinhole camera.
struct View {
    Vec3 eye{0.0, 1.0, 3.0};    ///< m
    Vec3 target{0.0, 1.0, 0.0}; ///< m
    double fov = 40.0;          ///< vertical field of view, degrees
    Vec3 up{0.0, 1.0, 0.0};     ///< approximate up direction (y is up in scenes)
};

/// A triangle mesh for drawTriangleMesh (paper sheets and cloths): pointers are not owned
/// and must stay valid for the call.
struct TriangleMesh {
    const std::vector<Vec3>* positions = nullptr;                  ///< per vertex, m
    const std::vector<std::array<std::uint32_t, 3>>* triangles = nullptr;  ///< vertex indices
    const std::vector<Rgb>* vertex_colors = nullptr;  ///< per vertex; nullptr = `color` everywhere
    Rgb color{0.92f, 0.90f, 0.84f};                   ///< used without vertex_colors
    /// Lines drawn over the surface (creases, tears): pairs of vertex indices.
    const std::vector<std::array<std::uint32_t, 2>>* lines = nullptr;
    Rgb line_color{0.25f, 0.22f, 0.20f};              ///< colour of `lines`
};

/// Draws into an offscreen OSMesa buffer (tearables_render). Not thread-safe; one at a time
/// per thread (OSMesa makes its context current on the calling thread). The viewer's build
/// of the same class (tearables_render_window) draws into the default framebuffer of the
/// OpenGL context the caller made current instead, with no supersampling; finish() then
/// reads the back buffer.
class Renderer {
public:
    /// An offscreen target of width x height pixels (each in [16, 8192]), rendered at
    /// `supersample` times that size and box-filtered down (anti-aliasing), 1..4.
    /// Throws std::runtime_error when OSMesa cannot create a context.
    Renderer(int width, int height, int supersample = 2);
    ~Renderer();
    Renderer(const Renderer&) = delete;
    Renderer& operator=(const Renderer&) = delete;

    /// A new picture size (each side in [16, 8192] pixels; a window's framebuffer size).
    void resize(int width, int height);

    int width() const { return width_; }
    int height() const { return height_; }

    /// Starts a frame: clears to a sky gradient, sets the camera and the lights. `near`/`far`
    /// clip distances, m (0 = chosen from the eye-target distance).
    void begin(const View& view, double near_clip = 0.0, double far_clip = 0.0);

    /// A ground plane n.x = offset (n unit) as a light tile floor with a grid, a square of
    /// half-width `extent` m around the point of the plane nearest `centre`.
    void drawGround(const Vec3& normal, double offset, const Vec3& centre, double extent);
    /// A grid only (no floor), for scenes without a ground: spacing chosen from `extent`.
    void drawReferenceGrid(const Vec3& normal, double offset, const Vec3& centre, double extent);

    /// A string as a shaded tube: segment j joins points[j] and points[j+1] with
    /// radius[j] m and colour colors[j]; segments with skip[j] != 0 (broken) are not drawn.
    /// A tube thinner than 3 pixels on screen is drawn that wide (a rope stays visible).
    void drawTube(const std::vector<Vec3>& points, const std::vector<double>& radius, const std::vector<Rgb>& colors,
                  const std::vector<std::uint8_t>& skip);

    /// Rigid shapes at a pose (position, body-to-world rotation).
    void drawBox(const Vec3& half_extents, const Vec3& position, const Quat& orientation, const Rgb& color);
    void drawSphere(double radius, const Vec3& position, const Quat& orientation, const Rgb& color);
    /// A capsule along its local y axis (as Bullet's btCapsuleShape).
    void drawCapsule(double radius, double half_height, const Vec3& position, const Quat& orientation, const Rgb& color);

    /// The generic entry point for surfaces (paper, cloth): a two-sided, smooth-shaded
    /// triangle mesh with per-vertex colours, and optional lines (creases) on top.
    void drawTriangleMesh(const TriangleMesh& mesh);

    /// Unlit line segments (pairs of points), `width` pixels wide.
    void drawLines(const std::vector<std::pair<Vec3, Vec3>>& lines, const Rgb& color, float width = 1.0f);

    /// Ends the frame and returns the picture.
    Image finish();

    /// Where a world point lands in the picture (pixels from the top-left corner) with the
    /// camera of the last begin(); nullopt behind the camera.
    std::optional<std::array<double, 2>> project(const Vec3& point) const;

    /// The size of a pixel at `point`, m (for minimum on-screen widths).
    double pixelSizeAt(const Vec3& point) const;

private:
    void drawGrid(const Vec3& normal, double offset, const Vec3& centre, double extent, const Rgb& line_color);
    struct Impl;
    std::unique_ptr<Impl> impl_;
    int width_ = 0;
    int height_ = 0;
};

}  // namespace tearables::render
