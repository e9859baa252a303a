// The default camera and the drawing of a scene's frame.
#include "render/scene_painter.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <set>

namespace tearables::render {

namespace {

/// Half extents of the world-axis box around a body's shape at its orientation, m.
Vec3 boundingHalfExtents(const scene::Shape& s, const Quat& orientation) {
    const Mat3 r = orientation.normalized().toRotationMatrix().cwiseAbs();
    switch (s.kind) {
        case scene::Shape::Kind::Box: return r * s.half_extents;
        case scene::Shape::Kind::Sphere: return Vec3::Constant(s.radius);
        case scene::Shape::Kind::Capsule: return r * Vec3(s.radius, s.radius + s.half_height, s.radius);
        case scene::Shape::Kind::Plane: return Vec3::Zero();
    }
    return Vec3::Zero();
}

/// Muted colours for dynamic bodies, by creation order; static bodies are grey.
Rgb bodyColor(const scene::FrameBody& body, std::size_t index, bool is_static) {
    if (is_static) return {0.55f, 0.56f, 0.60f};
    static const Rgb kPalette[] = {{0.72f, 0.52f, 0.32f}, {0.36f, 0.55f, 0.70f}, {0.45f, 0.65f, 0.42f},
                                   {0.75f, 0.42f, 0.38f}, {0.60f, 0.50f, 0.70f}};
    return kPalette[index % (sizeof kPalette / sizeof kPalette[0])];
}

/// Segment j's torsional strain over the rupture strain, clamped to [0, 1]: the mean over
/// its intact joints of gamma = r |theta_{k+1} - theta_k| / l, l the joint's mean rest
/// length (as src/string/fracture.cpp tears it). 0 without a rupture strain.
double torsionLoad(const StringView& v, std::size_t j, double rupture) {
    if (!(rupture > 0.0) || !v.twist || !v.rest_length || !v.broken) return 0.0;
    const std::size_t n = v.segmentCount();
    double sum = 0.0;
    int count = 0;
    for (std::size_t k : {j - 1, j}) {  // the joints (k, k+1) on either side; j - 1 wraps when j = 0
        if (k >= n || k + 1 >= n || (*v.broken)[k] || (*v.broken)[k + 1]) continue;
        const double l = 0.5 * ((*v.rest_length)[k] + (*v.rest_length)[k + 1]);
        if (!(l > 0.0)) continue;
        sum += v.radius * std::abs((*v.twist)[k + 1] - (*v.twist)[k]) / l;
        ++count;
    }
    const double load = count > 0 ? sum / count / rupture : 0.0;
    return std::isfinite(load) ? std::clamp(load, 0.0, 1.0) : 0.0;
}

/// A dark block where a string particle, a cloth vertex or a paper vertex is pinned to a world
/// point: three times the object's radius across, and never under 8 pixels (a pin stays
/// visible from afar).
void drawWorldPins(Renderer& renderer, const scene::Scene& scene, const scene::FrameState& frame) {
    const Rgb color{0.22f, 0.22f, 0.26f};
    const auto mark = [&](const Vec3& p, double radius) {
        if (!p.allFinite()) return;
        const double half = std::max(3.0 * radius, 4.0 * renderer.pixelSizeAt(p));
        renderer.drawBox(Vec3::Constant(half), p, Quat::Identity(), color);
    };
    for (const scene::String& s : scene.strings)
        for (const scene::Attachment& a : s.attachments)
            if (a.world) mark(*a.world, s.desc.radius);
    for (std::size_t k = 0; k < scene.cloths.size() && k < frame.cloths.size(); ++k) {
        const ClothDesc& d = scene.cloths[k].desc;
        const ClothView& v = frame.cloths[k].view;
        for (const SheetAttachment& a : d.attachments) {
            const int n = static_cast<int>(v.vertexCount());
            const int index = a.vertex < 0 ? a.vertex + n : a.vertex;
            if (!a.body.valid() && index >= 0 && index < n) mark(a.world.value_or((*v.positions)[static_cast<std::size_t>(index)]), d.yarn_radius);
        }
    }
    for (std::size_t k = 0; k < scene.papers.size() && k < frame.papers.size(); ++k) {
        const PaperView& v = frame.papers[k].view;
        const PaperDesc& d = scene.papers[k].desc;  // negative indices count from the end of its vertices at creation
        const int n = d.vertices.empty() ? d.resolution[0] * d.resolution[1] : static_cast<int>(d.vertices.size());
        for (const SheetAttachment& a : d.attachments) {
            const int index = a.vertex < 0 ? a.vertex + n : a.vertex;
            if (!a.body.valid() && index >= 0 && index < n && static_cast<std::size_t>(index) < v.vertexCount())
                mark(a.world.value_or((*v.positions)[static_cast<std::size_t>(index)]), d.thickness);
        }
    }
}

}  // namespace

void Bounds::add(const Vec3& p, double grow) {
    if (!p.allFinite()) return;
    lo = lo.cwiseMin(p - Vec3::Constant(grow));
    hi = hi.cwiseMax(p + Vec3::Constant(grow));
}

Bounds sceneBounds(const scene::Scene& scene) {
    Bounds b;
    for (const scene::String& s : scene.strings)
        for (const Vec3& p : s.desc.points) b.add(p, s.desc.radius);
    const auto addBody = [&](const scene::Body& body) {
        if (body.shape.kind == scene::Shape::Kind::Plane) return;
        const Vec3 h = boundingHalfExtents(body.shape, body.orientation);
        b.add(body.position - h);
        b.add(body.position + h);
    };
    // A rectangle's four corners, from its corner (vertex (0, 0)) or its centre.
    const auto addSheet = [&](const std::optional<Vec3>& center, const std::optional<Vec3>& corner, const Quat& q, double sx,
                              double sz, double pad) {
        const Mat3 r = q.normalized().toRotationMatrix();
        const Vec3 c0 = corner ? *corner : Vec3(center.value_or(defaultSheetCenter()) - r * Vec3(0.5 * sx, 0.0, 0.5 * sz));
        for (int k = 0; k < 4; ++k) b.add(c0 + r * Vec3((k & 1) ? sx : 0.0, 0.0, (k & 2) ? sz : 0.0), pad);
    };
    for (const scene::Cloth& c : scene.cloths)
        addSheet(c.desc.center, c.desc.corner, c.desc.orientation, c.desc.resolution[0] > 1 ? c.desc.size[0] : 0.0,
                 c.desc.resolution[1] > 1 ? c.desc.size[1] : 0.0, c.desc.yarn_radius);
    for (const scene::Paper& p : scene.papers) {
        if (!p.desc.vertices.empty()) {
            for (const Vec3& x : p.desc.vertices) b.add(x, p.desc.thickness);
            continue;
        }
        addSheet(p.desc.center, p.desc.corner, p.desc.orientation, p.desc.size[0], p.desc.size[1], p.desc.thickness);
    }
    for (const scene::Body& body : scene.bodies) addBody(body);
    for (const scene::Driver& d : scene.drivers)
        if (d.body) addBody(*d.body);
    if (b.empty()) b.add(Vec3::Zero(), 0.5);
    return b;
}

Bounds frameBounds(const scene::FrameState& frame) {
    Bounds b;
    for (const scene::FrameString& s : frame.strings)
        for (const Vec3& p : *s.view.positions) b.add(p, s.view.radius);
    for (const scene::FrameCloth& c : frame.cloths)
        for (const Vec3& p : *c.view.positions) b.add(p, c.view.yarn_radius);
    for (const scene::FramePaper& p : frame.papers)
        for (const Vec3& x : *p.view.positions) b.add(x);
    for (const scene::FrameBody& body : frame.bodies) {
        if (body.shape.kind == scene::Shape::Kind::Plane) continue;
        const Vec3 h = boundingHalfExtents(body.shape, body.orientation);
        b.add(body.position - h);
        b.add(body.position + h);
    }
    return b;
}

std::vector<double> clothDamage(const ClothView& v, const ClothDesc& desc) {
    const int nu = v.resolution[0], nv = v.resolution[1];
    const std::size_t n = v.vertexCount();
    std::vector<double> damage(n, 0.0);
    if (nu < 2 || nv < 2 || n != static_cast<std::size_t>(nu) * static_cast<std::size_t>(nv)) return damage;
    // A yarn's damage: 1 when torn; otherwise its permanent (plastic) strain over the one
    // it would keep at rupture. The yarns start at the grid spacing (src/cloth/mesh.cpp) and
    // plasticity lengthens them to (1 + eps_p) times that, where on the bilinear curve
    // eps_p(sigma) = sigma_y / E + (sigma - sigma_y) / H - sigma / E past yield (unloading
    // parallel to the elastic line; src/sim/material_curve.hpp).
    const TensileCurve& curve = desc.material.tensile;
    const double at_rupture =
        curve.yield / curve.young + (curve.rupture - curve.yield) / curve.plastic_modulus - curve.rupture / curve.young;
    const double spacing[2] = {desc.size[0] / (nu - 1), desc.size[1] / (nv - 1)};
    std::vector<double> right_damage(n, 0.0), up_damage(n, 0.0);  // the yarn to (i+1, j) / (i, j+1)
    for (std::size_t e = 0; e < v.edgeCount(); ++e) {
        const std::uint32_t lo = std::min((*v.edges)[e][0], (*v.edges)[e][1]), hi = std::max((*v.edges)[e][0], (*v.edges)[e][1]);
        if (hi >= n) continue;
        const bool right = hi == lo + 1, up = hi == lo + static_cast<std::uint32_t>(nu);
        if (!right && !up) continue;
        // (Rest lengths are measured between rotated grid points: under 1e-9 is rounding.)
        double plastic = (*v.rest_length)[e] / spacing[right ? 0 : 1] - 1.0;
        if (plastic < 1e-9) plastic = 0.0;
        double d = (*v.broken)[e] ? 1.0 : at_rupture > 0.0 ? plastic / at_rupture : 0.0;
        d = std::isfinite(d) ? std::clamp(d, 0.0, 1.0) : 0.0;
        (right ? right_damage : up_damage)[lo] = d;
    }
    // A cell is as damaged as its most damaged yarn; a vertex takes the mean of its cells.
    std::vector<int> cells(n, 0);
    std::vector<double> hurt(n, 0.0);
    for (int j = 0; j + 1 < nv; ++j)
        for (int i = 0; i + 1 < nu; ++i) {
            const auto idx = [nu](int u, int w) { return static_cast<std::size_t>(w) * static_cast<std::size_t>(nu) + static_cast<std::size_t>(u); };
            const std::size_t p00 = idx(i, j), p10 = idx(i + 1, j), p01 = idx(i, j + 1), p11 = idx(i + 1, j + 1);
            const double cell = std::max({right_damage[p00], up_damage[p00], right_damage[p01], up_damage[p10]});
            for (std::size_t p : {p00, p10, p01, p11}) {
                ++cells[p];
                hurt[p] += cell;
            }
        }
    for (std::size_t p = 0; p < n; ++p) damage[p] = cells[p] > 0 ? hurt[p] / cells[p] : 0.0;
    return damage;
}

std::vector<double> paperDamage(const PaperView& v, const PaperDesc& desc) {
    const std::size_t n = v.vertexCount();
    std::vector<double> damage(n, 0.0);
    if (!v.triangles || !v.springs) return damage;
    const auto key = [](std::uint32_t a, std::uint32_t b) {
        return (static_cast<std::uint64_t>(std::min(a, b)) << 32) | std::max(a, b);
    };
    // Which vertices were on the sheet's border at rest: the rectangle's edge rows and
    // columns, or the ends of the mesh's edges that belong to one triangle only.
    std::vector<std::uint8_t> border(n, 0);
    if (desc.vertices.empty()) {
        const int nu = desc.resolution[0], nv = desc.resolution[1];
        for (int k = 0; k < nv; ++k)
            for (int i = 0; i < nu; ++i) {
                const std::size_t p = static_cast<std::size_t>(desc.gridVertex(i, k));
                if (p < n && (i == 0 || k == 0 || i == nu - 1 || k == nv - 1)) border[p] = 1;
            }
    } else {
        std::map<std::uint64_t, int> uses;
        for (const auto& t : desc.triangles)
            for (int c = 0; c < 3; ++c) ++uses[key(t[c], t[(c + 1) % 3])];
        for (const auto& [edge, count] : uses)
            if (count == 1)
                for (std::uint64_t p : {edge >> 32, edge & 0xffffffffu})
                    if (p < n) border[p] = 1;
    }
    // A crease vertex inserted on a border edge is on the border (springs are appended in
    // order, so its edge's ends are settled before it); a vertex split by a tear is not.
    for (const PaperSpring& sp : *v.springs)
        if (sp.kind == PaperSpringKind::Auxiliary && sp.hinge[0] < n && sp.a < n && sp.b < n)
            border[sp.hinge[0]] = border[sp.a] && border[sp.b];
    std::set<std::uint64_t> damaged_edges;
    for (const auto& line : paperCreaseLines(v)) damaged_edges.insert(key(line[0], line[1]));
    std::map<std::uint64_t, int> uses;
    for (const auto& t : *v.triangles)
        for (int c = 0; c < 3; ++c) ++uses[key(t[c], t[(c + 1) % 3])];
    for (const auto& [edge, count] : uses) {
        const std::uint64_t a = edge >> 32, b = edge & 0xffffffffu;
        if (count == 1 && a < n && b < n && !(border[a] && border[b])) damaged_edges.insert(edge);
    }
    std::vector<int> faces(n, 0), hurt(n, 0);
    for (const auto& t : *v.triangles) {
        if (t[0] >= n || t[1] >= n || t[2] >= n) continue;
        bool damaged = false;
        for (int c = 0; c < 3; ++c) damaged = damaged || damaged_edges.count(key(t[c], t[(c + 1) % 3])) > 0;
        for (std::uint32_t p : t) {
            ++faces[p];
            hurt[p] += damaged;
        }
    }
    for (std::size_t p = 0; p < n; ++p) damage[p] = faces[p] > 0 ? static_cast<double>(hurt[p]) / faces[p] : 0.0;
    return damage;
}

void checkFollowable(const scene::Scene& scene, const std::string& name, const std::string& option) {
    std::vector<std::string> names;
    for (const scene::Body& b : scene.bodies) names.push_back(b.name);
    for (const scene::Driver& d : scene.drivers)
        if (d.body) names.push_back(d.body->name);
    for (const scene::String& s : scene.strings) names.push_back(s.desc.name);
    for (const scene::Cloth& c : scene.cloths) names.push_back(c.desc.name);
    for (const scene::Paper& p : scene.papers) names.push_back(p.desc.name);
    if (std::find(names.begin(), names.end(), name) != names.end()) return;
    std::string list;
    for (const std::string& n : names) list += (list.empty() ? "" : ", ") + n;
    throw InvalidInput(option, "no body, string, cloth or paper sheet named \"" + name + "\" in the scene (" +
                                   (list.empty() ? std::string("it names none") : "its names: " + list) + ")");
}

std::optional<Vec3> followPoint(const scene::FrameState& frame, const std::string& name) {
    for (const scene::FrameBody& b : frame.bodies)
        if (b.name == name && b.position.allFinite()) return b.position;
    Bounds bounds;
    for (const scene::FrameString& s : frame.strings)
        if (s.name == name)
            for (const Vec3& p : *s.view.positions) bounds.add(p);
    for (const scene::FrameCloth& c : frame.cloths)
        if (c.name == name)
            for (const Vec3& p : *c.view.positions) bounds.add(p);
    for (const scene::FramePaper& p : frame.papers)
        if (p.name == name)
            for (const Vec3& x : *p.view.positions) bounds.add(x);
    if (bounds.empty()) return std::nullopt;
    return Vec3(0.5 * (bounds.lo + bounds.hi));
}

View followView(const View& view, const Vec3& point) {
    View v = view;
    v.eye = point + (view.eye - view.target);
    v.target = point;
    return v;
}

View fitCamera(const scene::Scene& scene, double aspect) { return fitCamera(scene, aspect, sceneBounds(scene)); }

bool inFrame(const View& view, double aspect, const Bounds& bounds) {
    if (bounds.empty()) return true;
    const Vec3 forward = (view.target - view.eye).normalized();
    const Vec3 right = forward.cross(view.up).normalized();
    const Vec3 up = right.cross(forward);
    const double tan_v = std::tan(view.fov * M_PI / 360.0), tan_h = tan_v * aspect;
    for (int i = 0; i < 8; ++i) {
        const Vec3 corner((i & 1) ? bounds.hi.x() : bounds.lo.x(), (i & 2) ? bounds.hi.y() : bounds.lo.y(),
                          (i & 4) ? bounds.hi.z() : bounds.lo.z());
        const Vec3 d = corner - view.eye;
        const double z = d.dot(forward);
        if (!(z > 0.0) || std::abs(d.dot(right)) > z * tan_h || std::abs(d.dot(up)) > z * tan_v) return false;
    }
    return true;
}

View fitCamera(const scene::Scene& scene, double aspect, Bounds b) {
    // Room for what moves: ropes swing and stretch, bodies fall a little.
    const double grow = 0.08 * (b.hi - b.lo).norm();
    b.lo.array() -= grow;
    b.hi.array() += grow;
    View v;
    v.fov = scene.camera.fov;
    const Vec3 centre = 0.5 * (b.lo + b.hi);
    v.target = scene.camera.target.value_or(centre);
    if (scene.camera.eye) {
        v.eye = *scene.camera.eye;
        return v;
    }
    // From the front (+z), 20 degrees above; back off until every corner of the bounds is
    // inside the frustum (with a 10 % margin): for a corner at (x, y) across and z toward the
    // camera, the distance D must satisfy |x| <= (D - z) tan(hfov/2), |y| <= (D - z) tan(vfov/2).
    const Vec3 back = Vec3(0.0, std::sin(20.0 * M_PI / 180.0), std::cos(20.0 * M_PI / 180.0)).normalized();
    const Vec3 right = Vec3::UnitY().cross(back).normalized();
    const Vec3 up = back.cross(right);
    const double tan_v = std::tan(v.fov * M_PI / 360.0), tan_h = tan_v * aspect;
    double distance = 0.0;
    for (int i = 0; i < 8; ++i) {
        const Vec3 corner((i & 1) ? b.hi.x() : b.lo.x(), (i & 2) ? b.hi.y() : b.lo.y(), (i & 4) ? b.hi.z() : b.lo.z());
        const Vec3 d = corner - v.target;
        const double x = std::abs(d.dot(right)) * 1.1, y = std::abs(d.dot(up)) * 1.1, z = d.dot(back);
        distance = std::max({distance, x / tan_h + z, y / tan_v + z});
    }
    distance = std::max(distance, 0.05);
    v.eye = v.target + distance * back;
    return v;
}

Image paintFrame(Renderer& renderer, const scene::Scene& scene, const scene::FrameState& frame, const View& view,
                 RopeColors colors) {
    drawFrame(renderer, scene, frame, view, colors);
    return renderer.finish();
}

void drawFrame(Renderer& renderer, const scene::Scene& scene, const scene::FrameState& frame, const View& view,
               RopeColors rope_colors) {
    const Bounds b = sceneBounds(scene);
    const double size = std::max((b.hi - b.lo).norm(), 0.1);
    const double distance = (view.eye - view.target).norm();
    renderer.begin(view, distance * 0.01, distance * 10.0 + size * 20.0);
    // The floor and the grid go where the camera looks (a refitted or following camera keeps
    // them under it), wide enough to reach the picture's edges: at the target's depth the
    // picture is 2 d tan(fov/2) high, and from 20 degrees above the floor is seen up to a
    // few times that far.
    const Vec3 centre = view.target;
    const double half_view = distance * std::tan(view.fov * M_PI / 360.0);

    bool ground = false;
    for (std::size_t i = 0; i < frame.bodies.size(); ++i) {
        const scene::FrameBody& body = frame.bodies[i];
        const scene::Shape& s = body.shape;
        // A body neither in the scene nor spawned by it was added while running (the
        // viewer's crates): dynamic.
        bool is_static = false;
        for (const scene::Body& spec : scene.bodies)
            if (spec.name == body.name) is_static = spec.mass <= 0.0 || spec.kinematic;
        for (const scene::Driver& d : scene.drivers)
            if (d.body && d.body->name == body.name) is_static = d.body->mass <= 0.0 || d.body->kinematic;
        const Rgb c = bodyColor(body, i, is_static);
        switch (s.kind) {
            case scene::Shape::Kind::Plane:
                renderer.drawGround(s.plane_normal, s.plane_offset, centre, std::max({3.0 * size, 2.0, 8.0 * half_view}));
                ground = true;
                break;
            case scene::Shape::Kind::Box: renderer.drawBox(s.half_extents, body.position, body.orientation, c); break;
            case scene::Shape::Kind::Sphere: renderer.drawSphere(s.radius, body.position, body.orientation, c); break;
            case scene::Shape::Kind::Capsule:
                renderer.drawCapsule(s.radius, s.half_height, body.position, body.orientation, c);
                break;
        }
    }
    // Without a ground, a faint grid below the scene still gives depth and scale: below what
    // the scene starts with, and below the lower part of the view when the camera has moved
    // down (something fell).
    if (!ground)
        renderer.drawReferenceGrid(Vec3::UnitY(), std::min(b.lo.y() - 0.3 * size, view.target.y() - 0.9 * half_view), centre,
                                   std::max({1.5 * size, 1.0, 4.0 * half_view}));

    std::vector<double> radius;
    std::vector<Rgb> colors;
    for (const scene::FrameString& s : frame.strings) {
        const StringView& v = s.view;
        const std::size_t n = v.segmentCount();
        radius.assign(n, v.radius);
        colors.resize(n);
        for (std::size_t j = 0; j < n; ++j) {
            const double twist = torsionLoad(v, j, s.torsion_rupture);
            colors[j] = tensionColor(rope_colors == RopeColors::Twist
                                         ? twist
                                         : std::max(loadFraction((*v.tension)[j], s.rupture_stress, v.radius), twist));
        }
        renderer.drawTube(*v.positions, radius, colors, *v.broken);
    }
    drawWorldPins(renderer, scene, frame);
    // Cloths: the weave's quads as two triangles each, gone where a yarn of the quad is
    // torn (the mesh shows the cut); each vertex coloured by its damage (clothDamage).
    std::vector<std::array<std::uint32_t, 3>> triangles;
    std::vector<Rgb> vertex_colors;
    for (std::size_t k = 0; k < frame.cloths.size(); ++k) {
        const ClothView& v = frame.cloths[k].view;
        const int nu = v.resolution[0], nv = v.resolution[1];
        const std::size_t n = v.vertexCount();
        std::vector<std::uint8_t> cut_right(n, 0), cut_up(n, 0);  // the yarn to (i+1, j) / (i, j+1) is torn
        for (std::size_t e = 0; e < v.edgeCount(); ++e) {
            if (!(*v.broken)[e]) continue;
            const std::uint32_t lo = std::min((*v.edges)[e][0], (*v.edges)[e][1]), hi = std::max((*v.edges)[e][0], (*v.edges)[e][1]);
            if (hi >= n) continue;
            if (hi == lo + 1) cut_right[lo] = 1;
            else if (hi == lo + static_cast<std::uint32_t>(nu)) cut_up[lo] = 1;
        }
        const std::vector<double> damage =
            k < scene.cloths.size() ? clothDamage(v, scene.cloths[k].desc) : std::vector<double>(n, 0.0);
        vertex_colors.resize(n);
        for (std::size_t p = 0; p < n; ++p) vertex_colors[p] = tensionColor(damage[p]);
        triangles.clear();
        for (int j = 0; j + 1 < nv; ++j)
            for (int i = 0; i + 1 < nu; ++i) {
                const auto idx = [nu](int u, int w) { return static_cast<std::uint32_t>(w * nu + u); };
                const std::uint32_t p00 = idx(i, j), p10 = idx(i + 1, j), p01 = idx(i, j + 1), p11 = idx(i + 1, j + 1);
                if (cut_right[p00] || cut_up[p00] || cut_right[p01] || cut_up[p10]) continue;
                triangles.push_back({p00, p10, p11});
                triangles.push_back({p00, p11, p01});
            }
        TriangleMesh mesh;
        mesh.positions = v.positions;
        mesh.triangles = &triangles;
        mesh.vertex_colors = &vertex_colors;
        renderer.drawTriangleMesh(mesh);
    }
    // Paper sheets: the current triangles (creases insert vertices and split triangles),
    // each vertex coloured by its damage (paperDamage), and the creases and folds as dark
    // lines (paperCreaseLines).
    std::vector<std::array<std::uint32_t, 2>> lines;
    for (std::size_t k = 0; k < frame.papers.size(); ++k) {
        const PaperView& v = frame.papers[k].view;
        lines = paperCreaseLines(v);
        const std::vector<double> damage =
            k < scene.papers.size() ? paperDamage(v, scene.papers[k].desc) : std::vector<double>(v.vertexCount(), 0.0);
        vertex_colors.resize(v.vertexCount());
        for (std::size_t p = 0; p < v.vertexCount(); ++p) vertex_colors[p] = tensionColor(damage[p]);
        TriangleMesh mesh;
        mesh.positions = v.positions;
        mesh.triangles = v.triangles;
        mesh.vertex_colors = &vertex_colors;
        mesh.lines = &lines;
        mesh.line_color = {0.15f, 0.13f, 0.12f};
        renderer.drawTriangleMesh(mesh);
    }
}

}  // namespace tearables::render
