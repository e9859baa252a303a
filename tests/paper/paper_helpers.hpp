// Helpers for the paper tests: sheet measurements used by several tests.
#pragma once

#include "tearables/world.hpp"

#include <algorithm>
#include <cmath>

namespace tearables::testing {

/// Largest relative strain |l/l0 - 1| of the live structural springs.
inline double maxEdgeStrain(const PaperView& v) {
    double worst = 0.0;
    for (const PaperSpring& sp : *v.springs) {
        if (sp.broken || sp.kind != PaperSpringKind::Structural) continue;
        const double l = ((*v.positions)[sp.b] - (*v.positions)[sp.a]).norm();
        worst = std::max(worst, std::abs(l / sp.rest - 1.0));
    }
    return worst;
}

/// Largest vertex speed, m/s.
inline double maxSpeed(const PaperView& v) {
    double worst = 0.0;
    for (const Vec3& u : *v.velocities) worst = std::max(worst, u.norm());
    return worst;
}

/// True when every vertex position is finite.
inline bool allFinite(const PaperView& v) {
    for (const Vec3& x : *v.positions)
        if (!x.allFinite()) return false;
    return true;
}

/// Total mass, kg.
inline double totalMass(const PaperView& v) {
    double m = 0.0;
    for (double x : *v.masses) m += x;
    return m;
}

}  // namespace tearables::testing
