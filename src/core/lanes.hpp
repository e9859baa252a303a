// Two doubles in one SSE2 register (GCC's and Clang's vector extension): the lane type of
// kernels that run two independent dependency chains as the same instructions, such as
// the two sweeps of a twisted factorisation. Each lane computes exactly what scalar code
// computes (no FMA on the default x86-64 target).
#pragma once

namespace tearables::detail {

typedef double Lanes2 __attribute__((vector_size(16)));
typedef long long LaneMask2 __attribute__((vector_size(16)));

}  // namespace tearables::detail
