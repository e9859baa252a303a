// Two doubles in one SSE2 register (GCC's and Clang's vector extension): the lane type of
// kernels that run two independent dependency chains as the same instructions, such as
// the two sweeps of a twisted factorisation. Each lane computes exactly what scalar code
// computes (no FMA on the default x86-64 target).
#pragma once

#include <cmath>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace tearables::detail {

typedef double Lanes2 __attribute__((vector_size(16)));
typedef long long LaneMask2 __attribute__((vector_size(16)));

/// The square roots of both lanes, correctly rounded as std::sqrt's (one sqrtpd, which
/// costs what one sqrtsd does: where a loop takes two independent roots, half the time).
inline Lanes2 sqrt(Lanes2 v) {
#if defined(__SSE2__)
    return (Lanes2)_mm_sqrt_pd((__m128d)v);
#else
    return Lanes2{std::sqrt(v[0]), std::sqrt(v[1])};
#endif
}

}  // namespace tearables::detail
