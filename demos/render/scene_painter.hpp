// Pictures of headless scenes: the default camera fitted to a scene, and one frame of a run
// (FrameState) drawn with the Renderer: bodies, strings as tubes, cloths and paper sheets as
// triangle meshes (Renderer::drawTriangleMesh).
#pragma once

#include "render/renderer.hpp"
#include "tearables/scene.hpp"

#include <optional>
#include <string>
#include <vector>

namespace tearables::render {

/// What the strings' colours show: their load, the larger of tension over the rupture
/// tension and torsional strain over the torsional rupture strain (the default); or their
/// twist alone, the torsional share (the viewer's "twist" toggle).
enum class RopeColors { Load, Twist };

/// Axis-aligned bounds of what a scene holds at the start (string points, cloths, paper
/// sheets, bodies, spawned bodies; planes excluded), m.
struct Bounds {
    Vec3 lo = Vec3::Constant(1e300);
    Vec3 hi = Vec3::Constant(-1e300);
    bool empty() const { return !(lo.x() <= hi.x()); }
    void add(const Vec3& p, double grow = 0.0);
};
Bounds sceneBounds(const scene::Scene& scene);

/// The scene's camera: its "camera" field where given; what is absent is fitted so that the
/// scene's bounds fill the picture of the given aspect (width / height), seen from the front
/// (+z) and a little above.
View fitCamera(const scene::Scene& scene, double aspect);
/// As fitCamera around `bounds` instead of the scene's (grown by 8 % the same way).
View fitCamera(const scene::Scene& scene, double aspect, Bounds bounds);
/// Axis-aligned bounds of what a frame holds (string particles, cloth and paper vertices,
/// bodies but planes), m.
Bounds frameBounds(const scene::FrameState& frame);
/// True when every corner of `bounds` is in front of the camera and inside its picture of
/// the given aspect (width / height).
bool inFrame(const View& view, double aspect, const Bounds& bounds);

/// Checks a name for --follow: a body of the scene (or one it spawns), a string, a cloth or a
/// paper sheet. Throws InvalidInput naming `option` and listing the names when it is none.
void checkFollowable(const scene::Scene& scene, const std::string& name, const std::string& option = "--follow");
/// Where the named body, string, cloth or sheet is in a frame: a body's centre of mass, or
/// the middle of the bounds of the others' points, m; nullopt when the frame does not hold
/// it (a body not spawned yet).
std::optional<Vec3> followPoint(const scene::FrameState& frame, const std::string& name);
/// `view` carried along so that it looks at `point` from the same offset (a camera on a
/// dolly: the direction and the distance of the eye from the target are kept).
View followView(const View& view, const Vec3& point);

/// A cloth's damage per vertex, [0, 1]: the mean over the weave's cells around the vertex of
/// each cell's most damaged yarn, a yarn's damage being 1 when torn, otherwise its plastic
/// strain (rest length over the grid spacing of `desc`, less 1) over the plastic strain
/// `desc`'s material curve leaves at rupture.
std::vector<double> clothDamage(const ClothView& view, const ClothDesc& desc);
/// A paper sheet's damage per vertex, [0, 1]: the share of the triangles around the vertex
/// with an edge on a crease or fold (paperCreaseLines) or on a tear (an edge of the sheet's
/// border that was not on the border of `desc`'s mesh).
std::vector<double> paperDamage(const PaperView& view, const PaperDesc& desc);

/// Draws one frame: the ground (a plane body) or a reference grid, both around where `view`
/// looks (so they stay under a refitted or following camera), the rigid bodies, the
/// strings as tubes coloured by load (tension / rupture tension, colormap.hpp), broken
/// segments left out, world pins as dark blocks, cloths and paper sheets as surfaces
/// coloured by damage (clothDamage, paperDamage) with the creases and folds of paper in dark
/// lines; torn yarns open the cloth. Returns the picture.
Image paintFrame(Renderer& renderer, const scene::Scene& scene, const scene::FrameState& frame, const View& view,
                 RopeColors colors = RopeColors::Load);
/// As paintFrame without finishing the frame (the viewer draws more on top, then finishes).
void drawFrame(Renderer& renderer, const scene::Scene& scene, const scene::FrameState& frame, const View& view,
               RopeColors colors = RopeColors::Load);

}  // namespace tearables::render
