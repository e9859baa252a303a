// A small deterministic thread pool for the materials' independent stages.
//
// forEach(count, fn) calls fn(i) for i in [0, count) and returns when all calls have
// finished. Indices are split into fixed contiguous ranges, one per thread (the calling
// thread takes the first); which thread runs an index never changes what fn(i) computes,
// since callers only pass work whose items share nothing they write. So results are
// bit-identical for any thread count. Workers are started lazily on the first parallel
// call; no allocation per call. Between calls a worker first spins for kSpinMicroseconds
// (watching the call counter: pause instructions, then yielding the core) and then sleeps
// on a condition variable, and the caller waits for the workers the same way: calls in
// quick succession (the iterations of one solve) hand over without waking a sleeping
// thread, and yielding lets a waited-for thread run on a busy core.
//
// Nested calls run serially: a forEach made from inside a forEach's fn (on any thread)
// loops in place. So a stage may split one big string's work over the pool (a long
// rope stepped alone uses every core) and still be called from a forEach over many
// strings, where the cores are already busy.
#pragma once

#include "base/float_mode.hpp"

#include <condition_variable>
#include <cstddef>
#include <mutex>
#include <thread>
#include <type_traits>
#include <algorithm>
#include <atomic>
#include <chrono>
#include <vector>
#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#endif

namespace tearables::detail {

class ThreadPool {
public:
    ThreadPool() = default;
    ThreadPool(const ThreadPool&) = delete;
    ThreadPool& operator=(const ThreadPool&) = delete;
    ~ThreadPool() { stop(); }

    /// Threads to use from now on (the calling thread counts as one); 0 = hardware.
    void setThreads(int threads) {
        unsigned want = threads > 0 ? static_cast<unsigned>(threads) : std::thread::hardware_concurrency();
        if (want == 0) want = 1;
        if (want != threads_) {
            stop();
            threads_ = want;
        }
    }

    /// The threads a forEach uses (the calling thread counts as one).
    unsigned threads() const { return threads_; }

    /// True when a forEach made now would run on more than one thread (not nested).
    bool parallel() const { return threads_ > 1 && !inside_; }

    /// Calls fn(i) for every i in [0, count); parallel when worth it (count >= 2) and not
    /// nested in another forEach.
    template <class Fn>
    void forEach(std::size_t count, Fn&& fn) {
        if (!parallel() || count < 2) {
            for (std::size_t i = 0; i < count; ++i) fn(i);
            return;
        }
        start();
        const std::size_t parts = std::min<std::size_t>(threads_, count);
        {
            std::lock_guard<std::mutex> lock(mutex_);
            context_ = const_cast<void*>(static_cast<const void*>(&fn));
            call_ = [](void* f, std::size_t i) { (*static_cast<std::remove_reference_t<Fn>*>(f))(i); };
            count_ = count;
            parts_ = parts;
            pending_.store(parts - 1);
            generation_.fetch_add(1);
        }
        wake_.notify_all();
        run(0);
        spinWhile([&] { return pending_.load(std::memory_order_acquire) != 0; });
        std::unique_lock<std::mutex> lock(mutex_);
        done_.wait(lock, [&] { return pending_.load() == 0; });
        context_ = nullptr;
    }

private:
    void run(std::size_t part) const {
        const FlushSubnormals mode;  // the step's mode (float_mode.hpp), on every thread
        const std::size_t lo = count_ * part / parts_, hi = count_ * (part + 1) / parts_;
        const bool was_inside = inside_;
        inside_ = true;
        for (std::size_t i = lo; i < hi; ++i) call_(context_, i);
        inside_ = was_inside;
    }
    void start() {
        if (!workers_.empty()) return;
        quit_ = false;
        // Workers start from the current call count: a pool restarted with another
        // thread count must not take the last call (long finished) for a new one.
        const std::size_t now = generation_.load();
        for (unsigned t = 1; t < threads_; ++t) workers_.emplace_back([this, t, now] { loop(t, now); });
    }
    void stop() {
        {
            std::lock_guard<std::mutex> lock(mutex_);
            quit_ = true;
        }
        wake_.notify_all();
        for (std::thread& w : workers_) w.join();
        workers_.clear();
    }
    /// Spins while busy() holds, for at most kSpinMicroseconds: pause instructions first,
    /// then yielding the core (where the machine has more runnable threads than cores, the
    /// thread waited for may need this one).
    template <class Busy>
    static void spinWhile(Busy&& busy) {
        const auto start = std::chrono::steady_clock::now();
        for (unsigned i = 1; busy(); ++i) {
            if (i < kPauseSpins) {
#if defined(__x86_64__) || defined(__i386__)
                _mm_pause();
#endif
                continue;
            }
            std::this_thread::yield();
            if (std::chrono::steady_clock::now() - start > std::chrono::microseconds(kSpinMicroseconds)) return;
        }
    }
    void loop(std::size_t part, std::size_t seen) {
        for (;;) {
            spinWhile([&] { return generation_.load(std::memory_order_acquire) == seen && !quit_; });
            std::unique_lock<std::mutex> lock(mutex_);
            wake_.wait(lock, [&] { return quit_ || generation_.load() != seen; });
            if (quit_) return;
            seen = generation_.load();
            if (part >= parts_) continue;  // fewer items than threads this time
            lock.unlock();
            run(part);
            lock.lock();
            if (pending_.fetch_sub(1) == 1) done_.notify_one();
        }
    }

    unsigned threads_ = 1;
    std::vector<std::thread> workers_;
    std::mutex mutex_;
    std::condition_variable wake_, done_;
    void* context_ = nullptr;  // the caller's function object, called through call_
    void (*call_)(void*, std::size_t) = nullptr;
    static constexpr int kSpinMicroseconds = 200;
    static constexpr unsigned kPauseSpins = 1024;  // pause instructions before yielding
    std::size_t count_ = 0, parts_ = 1;
    std::atomic<std::size_t> pending_{0}, generation_{0};
    std::atomic<bool> quit_{false};
    static inline thread_local bool inside_ = false;  // this thread runs a forEach's fn
};

/// A loop over one string's particles or segments of this many or more is split over the
/// pool where it runs in parallel (a long rope alone uses every core); shorter loops are
/// not worth the hand-over.
constexpr std::size_t kParallelItems = 4096;

/// The most ranges forRanges cuts a loop into.
constexpr std::size_t kMaxRanges = 16;

/// Calls body(lo, hi, part) on [0, count) cut into one contiguous range per thread of
/// `pool` (at most kMaxRanges; part numbers them) when the pool runs in parallel now and
/// count >= min_count, else body(0, count, 0) here. For loops whose items write only their
/// own entries (the bits do not depend on the cut).
template <class Body>
void forRanges(ThreadPool* pool, std::size_t count, std::size_t min_count, Body&& body) {
    const std::size_t parts =
        pool && pool->parallel() && count >= min_count ? std::min<std::size_t>(pool->threads(), kMaxRanges) : 1;
    if (parts <= 1) {
        body(std::size_t{0}, count, std::size_t{0});
        return;
    }
    pool->forEach(parts, [&](std::size_t part) { body(count * part / parts, count * (part + 1) / parts, part); });
}

/// forRanges with a result per range, body(lo, hi) -> bool: whether any range's is true.
/// (Each range's is its own, so the answer does not depend on the cut.)
template <class Body>
bool forRangesAny(ThreadPool* pool, std::size_t count, std::size_t min_count, Body&& body) {
    bool any[kMaxRanges] = {};
    forRanges(pool, count, min_count, [&](std::size_t lo, std::size_t hi, std::size_t part) { any[part] = body(lo, hi); });
    return std::any_of(any, any + kMaxRanges, [](bool b) { return b; });
}

/// forRanges with a result per range, body(lo, hi) -> double: the largest, or 0 (max is
/// exact: the same on any cut).
template <class Body>
double forRangesMax(ThreadPool* pool, std::size_t count, std::size_t min_count, Body&& body) {
    double most[kMaxRanges] = {};
    forRanges(pool, count, min_count, [&](std::size_t lo, std::size_t hi, std::size_t part) { most[part] = body(lo, hi); });
    return *std::max_element(most, most + kMaxRanges);
}

}  // namespace tearables::detail
