// Two doubles in one SSE2 register (GCC's and Clang's vector extension): the lane type of
// kernels that run two independent dependency chains as the same instructions, such as
// the two sweeps of a twisted factorisation, and of loops that take two segments' square
// roots and divisions at once (the divider takes a pair in the time of one). Each lane
// computes exactly what scalar code computes (no FMA on the default x86-64 target). The
// helpers below write some operations as SSE2 intrinsics where GCC 12 compiled the vector
// extension's own forms badly; each has a portable fallback.
#pragma once

#include "tearables/types.hpp"

#include <cmath>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace tearables::detail {

typedef double Lanes2 __attribute__((vector_size(16)));
typedef long long LaneMask2 __attribute__((vector_size(16)));

/// The square roots of both lanes, correctly rounded as std::sqrt's (one sqrtpd, which
/// costs what one sqrtsd does: where a loop takes two independent roots, half the time).
inline Lanes2 sqrtLanes(Lanes2 v) {
#if defined(__SSE2__)
    return (Lanes2)_mm_sqrt_pd((__m128d)v);
#else
    return Lanes2{std::sqrt(v[0]), std::sqrt(v[1])};
#endif
}

/// v in the lanes where the mask m (all ones or all zeros per lane, as a comparison
/// gives) holds, else +0. The SSE2 instruction is written out: from the vector extension's
/// `&`, GCC 12 may take both lanes through general registers (a move out, a conditional
/// move and a move back per lane), on the chain solve's dependency chain.
inline Lanes2 maskLanes(LaneMask2 m, Lanes2 v) {
#if defined(__SSE2__)
    return (Lanes2)_mm_and_pd((__m128d)v, (__m128d)m);
#else
    return (Lanes2)((LaneMask2)v & m);
#endif
}

/// The lanes of v that are not zero (NaN is not zero), and the lanes where either mask
/// holds: SSE2's cmpneqpd and orpd, for the same reason as maskLanes.
inline LaneMask2 nonzeroLanes(Lanes2 v) {
#if defined(__SSE2__)
    return (LaneMask2)_mm_cmpneq_pd((__m128d)v, _mm_setzero_pd());
#else
    return v != Lanes2{0.0, 0.0};
#endif
}
inline LaneMask2 eitherLane(LaneMask2 a, LaneMask2 b) {
#if defined(__SSE2__)
    return (LaneMask2)_mm_or_pd((__m128d)a, (__m128d)b);
#else
    return a | b;
#endif
}

/// Two doubles from memory (no alignment needed) into lanes.
inline Lanes2 loadLanes(const double* p) {
#if defined(__SSE2__)
    return (Lanes2)_mm_loadu_pd(p);
#else
    return Lanes2{p[0], p[1]};
#endif
}

/// The lanes of the mask m as bits (bit 0 lane 0, bit 1 lane 1), and back.
inline int laneBits(LaneMask2 m) {
#if defined(__SSE2__)
    return _mm_movemask_pd((__m128d)m);
#else
    return (m[0] != 0 ? 1 : 0) | (m[1] != 0 ? 2 : 0);
#endif
}
inline LaneMask2 bitLanes(int bits) { return LaneMask2{-static_cast<long long>(bits & 1), -static_cast<long long>((bits >> 1) & 1)}; }

/// Lanes into two doubles of memory (no alignment needed).
inline void storeLanes(double* p, Lanes2 v) {
#if defined(__SSE2__)
    _mm_storeu_pd(p, (__m128d)v);
#else
    p[0] = v[0];
    p[1] = v[1];
#endif
}

/// Whether no lane of the mask m holds (one movmskpd with SSE2).
inline bool noLane(LaneMask2 m) { return laneBits(m) == 0; }

/// The lengths of two vectors, |a| and |b| as Eigen's norm() gives them, both roots in one
/// instruction.
inline Lanes2 lengthPair(const Vec3& a, const Vec3& b) { return sqrtLanes(Lanes2{a.squaredNorm(), b.squaredNorm()}); }

/// The lengths of two vectors (lengthPair) and their quotients a / |a|, b / |b| (as
/// Eigen's quotient by a scalar), the roots and divisions in lanes: the same bits as the
/// scalar expressions, at half their cost in the divider.
struct UnitPair {
    Lanes2 length;
    Vec3 unit[2];
};
inline UnitPair unitPair(const Vec3& a, const Vec3& b) {
    const Lanes2 len = lengthPair(a, b);
    const Lanes2 x = Lanes2{a.x(), b.x()} / len, y = Lanes2{a.y(), b.y()} / len, z = Lanes2{a.z(), b.z()} / len;
    return {len, {Vec3(x[0], y[0], z[0]), Vec3(x[1], y[1], z[1])}};
}

}  // namespace tearables::detail
