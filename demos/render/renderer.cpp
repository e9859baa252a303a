// The renderer: legacy fixed-function GL 1.x (two directional lights, smooth shading, colour
// material). Built twice from this file:
// - offscreen (tearables_render): Mesa's OSMesa gives a software OpenGL context that draws
//   into our own memory (no display, no GPU); images are rendered at `supersample` times
//   their size and box-filtered down, since OSMesa has no multisampling;
// - in a window (TEARABLES_RENDER_WINDOW, the viewer's tearables_render_window): the same
//   drawing into the default framebuffer of the OpenGL context the caller made current
//   (a GLFW window), linked against libGL instead of libOSMesa. Both libraries export the
//   gl* entry points, so no program links both.
#include "render/renderer.hpp"

#if !TEARABLES_RENDER_WINDOW
#include <GL/osmesa.h>
#endif
#include <GL/gl.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace tearables::render {

namespace {

using Mat4 = Eigen::Matrix4d;

/// The camera's view matrix (world -> eye), as gluLookAt.
Mat4 lookAt(const Vec3& eye, const Vec3& target, const Vec3& up_hint) {
    const Vec3 f = (target - eye).normalized();
    Vec3 up = up_hint;
    if (std::abs(f.dot(up.normalized())) > 0.999) up = std::abs(f.x()) < 0.9 ? Vec3::UnitX() : Vec3::UnitZ();
    const Vec3 s = f.cross(up).normalized();
    const Vec3 u = s.cross(f);
    Mat4 m = Mat4::Identity();
    m.block<1, 3>(0, 0) = s.transpose();
    m.block<1, 3>(1, 0) = u.transpose();
    m.block<1, 3>(2, 0) = -f.transpose();
    m(0, 3) = -s.dot(eye);
    m(1, 3) = -u.dot(eye);
    m(2, 3) = f.dot(eye);
    return m;
}

/// A perspective projection, as gluPerspective.
Mat4 perspective(double fov_deg, double aspect, double near_clip, double far_clip) {
    const double f = 1.0 / std::tan(fov_deg * M_PI / 360.0);
    Mat4 m = Mat4::Zero();
    m(0, 0) = f / aspect;
    m(1, 1) = f;
    m(2, 2) = (far_clip + near_clip) / (near_clip - far_clip);
    m(2, 3) = 2.0 * far_clip * near_clip / (near_clip - far_clip);
    m(3, 2) = -1.0;
    return m;
}

void vertex(const Vec3& p) { glVertex3d(p.x(), p.y(), p.z()); }
void normal(const Vec3& n) { glNormal3d(n.x(), n.y(), n.z()); }
void color(const Rgb& c) { glColor3f(c.r, c.g, c.b); }

/// Two unit vectors perpendicular to `axis` (unit) and to each other.
void basis(const Vec3& axis, Vec3& a, Vec3& b) {
    a = (std::abs(axis.x()) < 0.9 ? Vec3::UnitX() : Vec3::UnitY()).cross(axis).normalized();
    b = axis.cross(a);
}

/// Multiplies GL's modelview by a rigid pose.
void pushPose(const Vec3& position, const Quat& orientation) {
    glPushMatrix();
    Mat4 m = Mat4::Identity();
    m.block<3, 3>(0, 0) = orientation.normalized().toRotationMatrix();
    m.block<3, 1>(0, 3) = position;
    glMultMatrixd(m.data());  // Eigen is column-major, as GL
}

/// A unit sphere's band between latitudes, drawn as quad strips (normals = positions).
void sphereBand(double radius, double lat0, double lat1, double y_offset, int slices, int stacks) {
    for (int i = 0; i < stacks; ++i) {
        const double a0 = lat0 + (lat1 - lat0) * i / stacks, a1 = lat0 + (lat1 - lat0) * (i + 1) / stacks;
        glBegin(GL_QUAD_STRIP);
        for (int j = 0; j <= slices; ++j) {
            const double phi = 2.0 * M_PI * j / slices;
            for (double a : {a1, a0}) {
                const Vec3 n(std::cos(a) * std::cos(phi), std::sin(a), std::cos(a) * std::sin(phi));
                normal(n);
                vertex(radius * n + Vec3(0.0, y_offset, 0.0));
            }
        }
        glEnd();
    }
}

}  // namespace

struct Renderer::Impl {
#if !TEARABLES_RENDER_WINDOW
    OSMesaContext context = nullptr;
#endif
    int supersample = 2;
    int w = 0, h = 0;  // the buffer's size (supersampled)
    std::vector<std::uint8_t> buffer;  // RGBA, rows from the bottom (offscreen only)
    View view;
    Mat4 view_matrix = Mat4::Identity();
    Mat4 projection = Mat4::Identity();

    void makeCurrent() {
#if !TEARABLES_RENDER_WINDOW
        if (!OSMesaMakeCurrent(context, buffer.data(), GL_UNSIGNED_BYTE, w, h))
            throw std::runtime_error("OSMesa: cannot make the offscreen context current");
#endif
    }
};

namespace {
void checkSize(int width, int height) {
    if (width < 16 || height < 16 || width > 8192 || height > 8192)
        throw InvalidInput("size", "must be between 16x16 and 8192x8192 pixels (got " + std::to_string(width) + "x" +
                                       std::to_string(height) + ")");
}
}  // namespace

Renderer::Renderer(int width, int height, int supersample) : impl_(std::make_unique<Impl>()), width_(width), height_(height) {
    checkSize(width, height);
#if TEARABLES_RENDER_WINDOW
    impl_->supersample = 1;  // the window's own framebuffer
    impl_->w = width;
    impl_->h = height;
#else
    impl_->supersample = std::clamp(supersample, 1, 4);
    impl_->w = width * impl_->supersample;
    impl_->h = height * impl_->supersample;
    impl_->buffer.assign(static_cast<std::size_t>(impl_->w) * static_cast<std::size_t>(impl_->h) * 4, 0);
    impl_->context = OSMesaCreateContextExt(OSMESA_RGBA, 24, 0, 0, nullptr);
    if (!impl_->context) throw std::runtime_error("OSMesa: cannot create an offscreen OpenGL context");
    impl_->makeCurrent();
#endif
}

Renderer::~Renderer() {
#if !TEARABLES_RENDER_WINDOW
    if (impl_ && impl_->context) OSMesaDestroyContext(impl_->context);
#endif
}

void Renderer::resize(int width, int height) {
    checkSize(width, height);
    if (width == width_ && height == height_) return;
    width_ = width;
    height_ = height;
    impl_->w = width * impl_->supersample;
    impl_->h = height * impl_->supersample;
#if !TEARABLES_RENDER_WINDOW
    impl_->buffer.assign(static_cast<std::size_t>(impl_->w) * static_cast<std::size_t>(impl_->h) * 4, 0);
    impl_->makeCurrent();
#endif
}

void Renderer::begin(const View& view, double near_clip, double far_clip) {
    impl_->makeCurrent();
    impl_->view = view;
    const double distance = std::max((view.target - view.eye).norm(), 1e-6);
    if (!(near_clip > 0.0)) near_clip = distance * 0.01;
    if (!(far_clip > near_clip)) far_clip = distance * 200.0;
    impl_->view_matrix = lookAt(view.eye, view.target, view.up);
    impl_->projection = perspective(view.fov, static_cast<double>(width_) / height_, near_clip, far_clip);

    glViewport(0, 0, impl_->w, impl_->h);
    glClearColor(1, 1, 1, 1);
    glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);

    // The sky: a vertical gradient behind everything.
    glDisable(GL_DEPTH_TEST);
    glDisable(GL_LIGHTING);
    glMatrixMode(GL_PROJECTION);
    glLoadIdentity();
    glMatrixMode(GL_MODELVIEW);
    glLoadIdentity();
    glBegin(GL_QUADS);
    glColor3f(0.80f, 0.84f, 0.88f);
    glVertex2d(-1, -1);
    glVertex2d(1, -1);
    glColor3f(0.97f, 0.97f, 0.98f);
    glVertex2d(1, 1);
    glVertex2d(-1, 1);
    glEnd();

    glMatrixMode(GL_PROJECTION);
    glLoadMatrixd(impl_->projection.data());
    glMatrixMode(GL_MODELVIEW);
    glLoadMatrixd(impl_->view_matrix.data());

    glEnable(GL_DEPTH_TEST);
    glDepthFunc(GL_LEQUAL);
    glShadeModel(GL_SMOOTH);
    glEnable(GL_NORMALIZE);
    glEnable(GL_LIGHTING);
    // One-sided lighting: our normals are right whatever the winding; only sheets (seen from
    // both sides) turn two-sided lighting on.
    glLightModeli(GL_LIGHT_MODEL_TWO_SIDE, GL_FALSE);
    const GLfloat ambient[] = {0.28f, 0.28f, 0.30f, 1.0f};
    glLightModelfv(GL_LIGHT_MODEL_AMBIENT, ambient);
    // A key light from above, front and right, and a dimmer fill from the left; given in
    // world coordinates (the view matrix is loaded), w = 0: directional.
    const GLfloat key_dir[] = {0.45f, 0.85f, 0.55f, 0.0f};
    const GLfloat key[] = {0.75f, 0.73f, 0.70f, 1.0f};
    const GLfloat fill_dir[] = {-0.6f, 0.3f, 0.4f, 0.0f};
    const GLfloat fill[] = {0.25f, 0.27f, 0.32f, 1.0f};
    const GLfloat specular[] = {0.35f, 0.35f, 0.35f, 1.0f};
    const GLfloat none[] = {0.0f, 0.0f, 0.0f, 1.0f};
    glEnable(GL_LIGHT0);
    glLightfv(GL_LIGHT0, GL_POSITION, key_dir);
    glLightfv(GL_LIGHT0, GL_DIFFUSE, key);
    glLightfv(GL_LIGHT0, GL_SPECULAR, specular);
    glEnable(GL_LIGHT1);
    glLightfv(GL_LIGHT1, GL_POSITION, fill_dir);
    glLightfv(GL_LIGHT1, GL_DIFFUSE, fill);
    glLightfv(GL_LIGHT1, GL_SPECULAR, none);
    glEnable(GL_COLOR_MATERIAL);
    glColorMaterial(GL_FRONT_AND_BACK, GL_AMBIENT_AND_DIFFUSE);
    const GLfloat shine_color[] = {0.25f, 0.25f, 0.25f, 1.0f};
    glMaterialfv(GL_FRONT_AND_BACK, GL_SPECULAR, shine_color);
    glMaterialf(GL_FRONT_AND_BACK, GL_SHININESS, 24.0f);
    glDisable(GL_CULL_FACE);
}

void Renderer::drawGround(const Vec3& n_in, double offset, const Vec3& centre, double extent) {
    const Vec3 n = n_in.normalized();
    const Vec3 c = centre - n * (n.dot(centre) - offset);
    Vec3 a, b;
    basis(n, a, b);
    // The floor, pushed back in depth so that the grid lines on it win.
    glEnable(GL_POLYGON_OFFSET_FILL);
    glPolygonOffset(1.0f, 1.0f);
    glBegin(GL_QUADS);
    normal(n);
    glColor3f(0.86f, 0.85f, 0.82f);
    vertex(c - extent * a - extent * b);
    vertex(c + extent * a - extent * b);
    vertex(c + extent * a + extent * b);
    vertex(c - extent * a + extent * b);
    glEnd();
    glDisable(GL_POLYGON_OFFSET_FILL);
    drawGrid(n, offset, centre, extent, {0.66f, 0.66f, 0.65f});
}

void Renderer::drawReferenceGrid(const Vec3& normal_in, double offset, const Vec3& centre, double extent) {
    drawGrid(normal_in, offset, centre, extent, {0.74f, 0.76f, 0.80f});
}

void Renderer::drawGrid(const Vec3& n_in, double offset, const Vec3& centre, double extent, const Rgb& line_color) {
    const Vec3 n = n_in.normalized();
    Vec3 a, b;
    basis(n, a, b);
    // Lines on multiples of the spacing along a and b, so the grid stays put as the centre moves.
    // A round spacing (1, 2 or 5 times a power of ten) giving 4 to 10 lines each side.
    double spacing = std::pow(10.0, std::floor(std::log10(std::max(extent, 1e-6) / 4.0)));
    if (extent / spacing > 20.0) spacing *= 5.0;
    else if (extent / spacing > 10.0) spacing *= 2.0;
    const Vec3 origin = n * offset;
    const double ca = (centre - origin).dot(a), cb = (centre - origin).dot(b);
    const int count = static_cast<int>(std::ceil(extent / spacing));
    std::vector<std::pair<Vec3, Vec3>> lines;
    const double a0 = std::round(ca / spacing) * spacing, b0 = std::round(cb / spacing) * spacing;
    for (int i = -count; i <= count; ++i) {
        const double sa = a0 + i * spacing, sb = b0 + i * spacing;
        lines.emplace_back(origin + sa * a + (b0 - extent) * b, origin + sa * a + (b0 + extent) * b);
        lines.emplace_back(origin + (a0 - extent) * a + sb * b, origin + (a0 + extent) * a + sb * b);
    }
    drawLines(lines, line_color, 1.0f);
}

double Renderer::pixelSizeAt(const Vec3& point) const {
    const Vec3 forward = (impl_->view.target - impl_->view.eye).normalized();
    const double depth = std::max((point - impl_->view.eye).dot(forward), 1e-6);
    return 2.0 * depth * std::tan(impl_->view.fov * M_PI / 360.0) / height_;
}

void Renderer::drawTube(const std::vector<Vec3>& points, const std::vector<double>& radius, const std::vector<Rgb>& colors,
                        const std::vector<std::uint8_t>& skip) {
    // 16 sides: the polygon's silhouette is within cos(pi/16) (2 %) of the true diameter.
    constexpr int kSides = 16;
    const std::size_t segments = points.size() < 2 ? 0 : points.size() - 1;
    for (std::size_t j = 0; j < segments; ++j) {
        if (j < skip.size() && skip[j]) continue;
        const Vec3& p0 = points[j];
        const Vec3& p1 = points[j + 1];
        const Vec3 d = p1 - p0;
        const double length = d.norm();
        if (!(length > 0.0) || !p0.allFinite() || !p1.allFinite()) continue;
        const double r = std::max(j < radius.size() ? radius[j] : 0.0, 1.5 * pixelSizeAt(0.5 * (p0 + p1)));
        const Vec3 axis = d / length;
        Vec3 a, b;
        basis(axis, a, b);
        color(j < colors.size() ? colors[j] : Rgb{0.5f, 0.5f, 0.5f});
        glBegin(GL_QUAD_STRIP);
        for (int k = 0; k <= kSides; ++k) {
            const double phi = 2.0 * M_PI * k / kSides;
            const Vec3 n = std::cos(phi) * a + std::sin(phi) * b;
            normal(n);
            vertex(p1 + r * n);
            vertex(p0 + r * n);
        }
        glEnd();
        // Round joints hide the gaps where consecutive segments bend.
        for (const Vec3& p : {p0, p1}) {
            glPushMatrix();
            glTranslated(p.x(), p.y(), p.z());
            sphereBand(r, -M_PI / 2, M_PI / 2, 0.0, 8, 4);
            glPopMatrix();
        }
    }
}

void Renderer::drawBox(const Vec3& h, const Vec3& position, const Quat& orientation, const Rgb& c) {
    pushPose(position, orientation);
    color(c);
    glBegin(GL_QUADS);
    for (int axis = 0; axis < 3; ++axis) {
        for (int sign : {-1, 1}) {
            Vec3 n = Vec3::Zero();
            n[axis] = sign;
            const int u = (axis + 1) % 3, v = (axis + 2) % 3;
            normal(n);
            for (const auto& [su, sv] : {std::pair{-1, -1}, {1, -1}, {1, 1}, {-1, 1}}) {
                Vec3 p = Vec3::Zero();
                p[axis] = sign * h[axis];
                p[u] = su * h[u];
                p[v] = sign * sv * h[v];
                vertex(p);
            }
        }
    }
    glEnd();
    glPopMatrix();
    // Dark edges make boxes read as boxes at small sizes.
    const Mat3 r = orientation.normalized().toRotationMatrix();
    std::vector<std::pair<Vec3, Vec3>> edges;
    for (int axis = 0; axis < 3; ++axis) {
        const int u = (axis + 1) % 3, v = (axis + 2) % 3;
        for (int su : {-1, 1})
            for (int sv : {-1, 1}) {
                Vec3 p0 = Vec3::Zero();
                p0[u] = su * h[u];
                p0[v] = sv * h[v];
                Vec3 p1 = p0;
                p0[axis] = -h[axis];
                p1[axis] = h[axis];
                edges.emplace_back(position + r * p0, position + r * p1);
            }
    }
    drawLines(edges, {c.r * 0.45f, c.g * 0.45f, c.b * 0.45f}, 1.0f);
}

void Renderer::drawSphere(double radius, const Vec3& position, const Quat& orientation, const Rgb& c) {
    pushPose(position, orientation);
    color(c);
    sphereBand(radius, -M_PI / 2, M_PI / 2, 0.0, 24, 12);
    glPopMatrix();
}

void Renderer::drawCapsule(double radius, double half_height, const Vec3& position, const Quat& orientation, const Rgb& c) {
    pushPose(position, orientation);
    color(c);
    constexpr int kSlices = 24;
    glBegin(GL_QUAD_STRIP);
    for (int j = 0; j <= kSlices; ++j) {
        const double phi = 2.0 * M_PI * j / kSlices;
        const Vec3 n(std::cos(phi), 0.0, std::sin(phi));
        normal(n);
        vertex(radius * n + Vec3(0.0, half_height, 0.0));
        vertex(radius * n - Vec3(0.0, half_height, 0.0));
    }
    glEnd();
    sphereBand(radius, 0.0, M_PI / 2, half_height, kSlices, 6);
    sphereBand(radius, -M_PI / 2, 0.0, -half_height, kSlices, 6);
    glPopMatrix();
}

void Renderer::drawTriangleMesh(const TriangleMesh& mesh) {
    if (!mesh.positions || !mesh.triangles) return;
    const std::vector<Vec3>& x = *mesh.positions;
    // Smooth normals: area-weighted sums of the faces around each vertex.
    std::vector<Vec3> normals(x.size(), Vec3::Zero());
    for (const auto& t : *mesh.triangles) {
        if (t[0] >= x.size() || t[1] >= x.size() || t[2] >= x.size()) continue;
        const Vec3 n = (x[t[1]] - x[t[0]]).cross(x[t[2]] - x[t[0]]);
        for (std::uint32_t v : t) normals[v] += n;
    }
    const bool per_vertex = mesh.vertex_colors && mesh.vertex_colors->size() == x.size();
    // Sheets are seen from both sides: two-sided lighting flips the normal on the back; the
    // triangles' winding must then agree with their normals, which it does by construction.
    glLightModeli(GL_LIGHT_MODEL_TWO_SIDE, GL_TRUE);
    glEnable(GL_POLYGON_OFFSET_FILL);
    glPolygonOffset(1.0f, 1.0f);
    glBegin(GL_TRIANGLES);
    color(mesh.color);
    for (const auto& t : *mesh.triangles) {
        if (t[0] >= x.size() || t[1] >= x.size() || t[2] >= x.size()) continue;
        for (std::uint32_t v : t) {
            if (per_vertex) color((*mesh.vertex_colors)[v]);
            normal(normals[v].squaredNorm() > 0.0 ? normals[v] : Vec3::UnitY());
            vertex(x[v]);
        }
    }
    glEnd();
    glDisable(GL_POLYGON_OFFSET_FILL);
    glLightModeli(GL_LIGHT_MODEL_TWO_SIDE, GL_FALSE);
    if (mesh.lines) {
        std::vector<std::pair<Vec3, Vec3>> lines;
        for (const auto& l : *mesh.lines)
            if (l[0] < x.size() && l[1] < x.size()) lines.emplace_back(x[l[0]], x[l[1]]);
        drawLines(lines, mesh.line_color, 1.5f);
    }
}

void Renderer::drawLines(const std::vector<std::pair<Vec3, Vec3>>& lines, const Rgb& c, float width) {
    glDisable(GL_LIGHTING);
    glLineWidth(width * static_cast<float>(impl_->supersample));
    color(c);
    glBegin(GL_LINES);
    for (const auto& [p, q] : lines) {
        vertex(p);
        vertex(q);
    }
    glEnd();
    glEnable(GL_LIGHTING);
}

Image Renderer::finish() {
    glFinish();
#if TEARABLES_RENDER_WINDOW
    // The frame is in the back buffer until the caller swaps: read it from there.
    impl_->buffer.assign(static_cast<std::size_t>(impl_->w) * static_cast<std::size_t>(impl_->h) * 4, 0);
    glPixelStorei(GL_PACK_ALIGNMENT, 1);
    glReadBuffer(GL_BACK);
    glReadPixels(0, 0, impl_->w, impl_->h, GL_RGBA, GL_UNSIGNED_BYTE, impl_->buffer.data());
#endif
    const int s = impl_->supersample;
    Image image;
    image.width = width_;
    image.height = height_;
    image.rgb.resize(static_cast<std::size_t>(width_) * height_ * 3);
    for (int y = 0; y < height_; ++y) {
        for (int x = 0; x < width_; ++x) {
            unsigned sum[3] = {0, 0, 0};
            for (int dy = 0; dy < s; ++dy)
                for (int dx = 0; dx < s; ++dx) {
                    // OSMesa's rows run from the bottom; the image's from the top.
                    const int by = impl_->h - 1 - (y * s + dy), bx = x * s + dx;
                    const std::uint8_t* p = &impl_->buffer[(static_cast<std::size_t>(by) * impl_->w + bx) * 4];
                    for (int c = 0; c < 3; ++c) sum[c] += p[c];
                }
            for (int c = 0; c < 3; ++c)
                image.rgb[(static_cast<std::size_t>(y) * width_ + x) * 3 + c] = static_cast<std::uint8_t>(sum[c] / (s * s));
        }
    }
    return image;
}

std::optional<std::array<double, 2>> Renderer::project(const Vec3& point) const {
    const Eigen::Vector4d clip = impl_->projection * impl_->view_matrix * point.homogeneous();
    if (!(clip.w() > 0.0)) return std::nullopt;
    const double nx = clip.x() / clip.w(), ny = clip.y() / clip.w();
    return std::array<double, 2>{(nx + 1.0) * 0.5 * width_, (1.0 - ny) * 0.5 * height_};
}

}  // namespace tearables::render
