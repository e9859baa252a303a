// The weave: vertices, yarn edges (warp then weft), soft shear and bending springs, masses
// and per-edge material; and the prediction stage.
#include "base/constants.hpp"
#include "cloth/cloth_state.hpp"
#include "sim/sheet_attachments.hpp"

#include <algorithm>
#include <cmath>

namespace tearables::detail {

ClothState makeCloth(const ClothDesc& desc) {
    ClothState c;
    c.desc = desc;
    c.desc.orientation.normalize();
    const int nu = desc.resolution[0], nv = desc.resolution[1];
    c.nu = nu;
    c.nv = nv;
    const std::size_t n = static_cast<std::size_t>(nu) * static_cast<std::size_t>(nv);
    const double dx = nu > 1 ? desc.size[0] / (nu - 1) : 0.0;
    const double dz = nv > 1 ? desc.size[1] / (nv - 1) : 0.0;
    const Mat3 rot = c.desc.orientation.toRotationMatrix();
    auto index = [nu](int i, int j) { return static_cast<std::uint32_t>(j * nu + i); };
    c.x.resize(n);
    // Vertex (i, j) from the corner: (i dx, 0, j dz) in the cloth's frame; from the centre,
    // the same less half the extent along each axis (a paper sheet's grid, paper/desc.cpp,
    // places its vertices the same way). An axis of resolution 1 has no extent.
    if (desc.corner) {
        for (int j = 0; j < nv; ++j)
            for (int i = 0; i < nu; ++i) c.x[index(i, j)] = *desc.corner + rot * Vec3(i * dx, 0.0, j * dz);
    } else {
        const Vec3 center = desc.center.value_or(defaultSheetCenter());
        const double hx = nu > 1 ? 0.5 * desc.size[0] : 0.0, hz = nv > 1 ? 0.5 * desc.size[1] : 0.0;
        for (int j = 0; j < nv; ++j)
            for (int i = 0; i < nu; ++i) {
                const double u = nu > 1 ? desc.size[0] * i / (nu - 1) : 0.0, w = nv > 1 ? desc.size[1] * j / (nv - 1) : 0.0;
                c.x[index(i, j)] = center + rot * Vec3(u - hx, 0.0, w - hz);
            }
    }
    c.v.assign(n, Vec3::Zero());
    c.x_prev = c.x;
    c.x_pred = c.x;
    c.force.assign(n, Vec3::Zero());
    c.hold.assign(n, ParticleHold{});
    c.mass.assign(n, 0.0);

    // Yarn edges: warp (along x) first, then weft (along z).
    for (int j = 0; j < nv; ++j)
        for (int i = 0; i + 1 < nu; ++i) {
            c.edges.push_back({index(i, j), index(i + 1, j)});
            c.kinds.push_back(YarnKind::Warp);
        }
    for (int j = 0; j + 1 < nv; ++j)
        for (int i = 0; i < nu; ++i) {
            c.edges.push_back({index(i, j), index(i, j + 1)});
            c.kinds.push_back(YarnKind::Weft);
        }
    const std::size_t m = c.edges.size();
    const std::size_t warp_count = static_cast<std::size_t>(nu - 1) * static_cast<std::size_t>(nv);
    auto warp = [&](int i, int j) { return static_cast<std::uint32_t>(j * (nu - 1) + i); };
    auto weft = [&](int i, int j) { return static_cast<std::uint32_t>(warp_count + static_cast<std::size_t>(j * nu + i)); };

    const double area = kPi * desc.yarn_radius * desc.yarn_radius;
    c.rest_length.resize(m);
    for (std::size_t e = 0; e < m; ++e) c.rest_length[e] = (c.x[c.edges[e][1]] - c.x[c.edges[e][0]]).norm();
    if (desc.areal_density > 0.0) {
        // A quarter of each cell's mass on each of its corners.
        const double quarter = 0.25 * desc.areal_density * dx * dz;
        for (int j = 0; j + 1 < nv; ++j)
            for (int i = 0; i + 1 < nu; ++i)
                for (std::uint32_t p : {index(i, j), index(i + 1, j), index(i, j + 1), index(i + 1, j + 1)}) c.mass[p] += quarter;
    } else {
        for (std::size_t e = 0; e < m; ++e) {
            const double half = 0.5 * desc.density * area * c.rest_length[e];
            c.mass[c.edges[e][0]] += half;
            c.mass[c.edges[e][1]] += half;
        }
    }
    c.original_length = c.rest_length;
    c.max_length = c.rest_length;
    c.tension.assign(m, 0.0);
    c.broken.assign(m, 0);
    c.yielded.assign(m, 0);
    c.peak_stress.assign(m, 0.0);
    c.rng.seed(desc.seed);
    c.material.resize(m);
    const TensileCurve& t = desc.material.tensile;
    for (std::size_t e = 0; e < m; ++e) {
        SegmentMaterial& sm = c.material[e];
        sm.young = vary(c.rng, t.young, desc.material.variation);
        sm.yield = vary(c.rng, t.yield, desc.material.variation);
        sm.plastic_modulus = vary(c.rng, t.plastic_modulus, desc.material.variation);
        sm.rupture = std::max(vary(c.rng, t.rupture, desc.material.variation), sm.yield * (1.0 + 1e-12));
        sm.shear_modulus = sm.torsion_yield = sm.torsion_plastic = sm.torsion_rupture = 0.0;  // cloth: no torsion
    }
    // Weak yarns (flaws, notches): the same curve with lower stresses, so that the tear
    // starts where the scene says and not where rounding puts the largest of equal tensions.
    for (const ClothWeakYarn& w : desc.weak_yarns) {
        const int i = w.i < 0 ? w.i + nu : w.i, j = w.j < 0 ? w.j + nv : w.j;
        SegmentMaterial& sm = c.material[w.kind == YarnKind::Warp ? warp(i, j) : weft(i, j)];
        sm.yield *= w.strength;
        sm.rupture *= w.strength;
    }
    // Stiff axial springs k = E A / L (engineering: E on the original section); the
    // strain-limit solve meets L_max = L (1 + sigma / E) through them implicitly.
    c.stiffness.resize(m);
    for (std::size_t e = 0; e < m; ++e) c.stiffness[e] = c.material[e].young * area / c.rest_length[e];
    c.shortest_rest = *std::min_element(c.rest_length.begin(), c.rest_length.end());

    // Soft springs, each removed with the yarns it depends on.
    c.edge_springs.assign(m, {});
    auto addSpring = [&](std::uint32_t a, std::uint32_t b, double stiffness_per_strain, std::initializer_list<std::uint32_t> deps) {
        if (stiffness_per_strain <= 0.0) return;
        SoftSpring s;
        s.a = a;
        s.b = b;
        s.rest = (c.x[b] - c.x[a]).norm();
        s.stiffness = stiffness_per_strain / s.rest;
        const auto id = static_cast<std::uint32_t>(c.springs.size());
        c.springs.push_back(s);
        for (std::uint32_t e : deps) c.edge_springs[e].push_back(id);
    };
    for (int j = 0; j + 1 < nv; ++j)
        for (int i = 0; i + 1 < nu; ++i) {
            // Shear: the two diagonals of cell (i, j), gone when any yarn of the cell tears.
            const std::initializer_list<std::uint32_t> cell = {warp(i, j), warp(i, j + 1), weft(i, j), weft(i + 1, j)};
            addSpring(index(i, j), index(i + 1, j + 1), desc.shear_stiffness, cell);
            addSpring(index(i + 1, j), index(i, j + 1), desc.shear_stiffness, cell);
        }
    for (int j = 0; j < nv; ++j)
        for (int i = 0; i + 2 < nu; ++i) addSpring(index(i, j), index(i + 2, j), desc.bending_stiffness, {warp(i, j), warp(i + 1, j)});
    for (int j = 0; j + 2 < nv; ++j)
        for (int i = 0; i < nu; ++i) addSpring(index(i, j), index(i, j + 2), desc.bending_stiffness, {weft(i, j), weft(i, j + 1)});

    c.vertex_edges.assign(n, {});
    for (std::size_t e = 0; e < m; ++e)
        for (std::uint32_t p : c.edges[e]) c.vertex_edges[p].push_back(static_cast<std::uint32_t>(e));

    // World pins; glues to bodies are set by ClothSystem::add, which has the bodies.
    const std::vector<std::size_t> held = resolveSheetAttachments(desc.attachments, n, "cloth");
    for (std::size_t k = 0; k < held.size(); ++k) {
        const SheetAttachment& a = desc.attachments[k];
        if (a.body.valid()) continue;
        const std::size_t p = held[k];
        c.hold[p].kind = ParticleHold::Kind::Pin;
        c.hold[p].point = a.world ? *a.world : c.x[p];
        c.x[p] = c.x_prev[p] = c.x_pred[p] = c.hold[p].point;
    }

    c.dof.assign(n, -1);
    c.projector.assign(n, Mat3::Identity());
    c.has_row.assign(n, 0);
    c.row_rhs.assign(n, Vec3::Zero());
    c.dir.assign(m, Vec3::UnitX());
    c.unknown.assign(m, -1);
    c.x_trial = c.x;
    return c;
}

void predictCloth(ClothState& c, const RigidTable& rigids, const StepContext& ctx) {
    const double h = ctx.h;
    const double keep = 1.0 / (1.0 + c.desc.damping * h);
    for (std::size_t p = 0; p < c.vertices(); ++p) {
        c.x_prev[p] = c.x[p];
        const ParticleHold& hold = c.hold[p];
        if (hold.kind == ParticleHold::Kind::Pin) {
            c.x_pred[p] = c.x[p] = hold.point;
            continue;
        }
        if (hold.kind == ParticleHold::Kind::Glue) {
            // Where the body (already moved by the host) carries the glue point.
            c.x_pred[p] = c.x[p] = gluePoint(rigids.bodies[hold.body.index], hold.point);
            continue;
        }
        c.v[p] *= keep;
        c.v[p] += h * (ctx.gravity + c.force[p] / c.mass[p]);
        c.x_pred[p] = c.x[p] + h * c.v[p];
        c.x[p] = c.x_pred[p];
    }
}

}  // namespace tearables::detail
