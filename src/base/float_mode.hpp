// The floating-point mode the step runs in: subnormal numbers flushed to zero.
//
// A value that decays geometrically along a long chain passes through the subnormal
// range (below 2.2e-308) on its way to zero, and on Intel cores each operation on a
// subnormal operand or result takes a microcode assist of ~100 cycles (the chain solve's
// gains along a long straight rope: docs/benchmarks-history.md, tenth round). Such
// values are far below anything the simulation resolves (a position's rounding is ~1e-16
// of its size), so the step flushes them: flush-to-zero (results) and denormals-are-zero
// (operands) in MXCSR, set for the step and restored after it, and set by the pool's
// workers for each call (ThreadPool::run), so every thread computes the same bits. Other
// platforms keep their mode: ARM cores handle subnormals at full speed.
#pragma once

#if defined(__SSE2__)
#include <xmmintrin.h>
#endif

namespace tearables::detail {

/// Flushes subnormals to zero on this thread while it lives; restores the thread's mode
/// (whatever the caller had set) when it ends.
class FlushSubnormals {
public:
#if defined(__SSE2__)
    FlushSubnormals() : saved_(_mm_getcsr()) {
        constexpr unsigned kFlushToZero = 0x8000, kDenormalsAreZero = 0x0040;
        const unsigned want = saved_ | kFlushToZero | kDenormalsAreZero;
        if (want != saved_) _mm_setcsr(want);
    }
    ~FlushSubnormals() {
        if (_mm_getcsr() != saved_) _mm_setcsr(saved_);
    }
#else
    FlushSubnormals() = default;
#endif
    FlushSubnormals(const FlushSubnormals&) = delete;
    FlushSubnormals& operator=(const FlushSubnormals&) = delete;

private:
#if defined(__SSE2__)
    unsigned saved_;
#endif
};

}  // namespace tearables::detail
