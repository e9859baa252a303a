// A small deterministic thread pool for the strings' independent stages (issue 9).
//
// forEach(count, fn) calls fn(i) for i in [0, count) and returns when all calls have
// finished. Indices are split into fixed contiguous ranges, one per thread (the calling
// thread takes the first); which thread runs an index never changes what fn(i) computes,
// since callers only pass work whose items share nothing they write. So results are
// bit-identical for any thread count. Workers are started lazily on the first parallel
// call and wait on a condition variable between calls; no allocation per call.
#pragma once

#include <condition_variable>
#include <cstddef>
#include <mutex>
#include <thread>
#include <type_traits>
#include <algorithm>
#include <vector>

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

    /// Calls fn(i) for every i in [0, count); parallel when worth it (count >= 2).
    template <class Fn>
    void forEach(std::size_t count, Fn&& fn) {
        if (threads_ <= 1 || count < 2) {
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
            pending_ = parts - 1;
            ++generation_;
        }
        wake_.notify_all();
        run(0);
        std::unique_lock<std::mutex> lock(mutex_);
        done_.wait(lock, [&] { return pending_ == 0; });
        context_ = nullptr;
    }

private:
    void run(std::size_t part) const {
        const std::size_t lo = count_ * part / parts_, hi = count_ * (part + 1) / parts_;
        for (std::size_t i = lo; i < hi; ++i) call_(context_, i);
    }
    void start() {
        if (!workers_.empty()) return;
        quit_ = false;
        for (unsigned t = 1; t < threads_; ++t) workers_.emplace_back([this, t] { loop(t); });
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
    void loop(std::size_t part) {
        std::size_t seen = 0;
        for (;;) {
            std::unique_lock<std::mutex> lock(mutex_);
            wake_.wait(lock, [&] { return quit_ || generation_ != seen; });
            if (quit_) return;
            seen = generation_;
            if (part >= parts_) continue;  // fewer items than threads this time
            lock.unlock();
            run(part);
            lock.lock();
            if (--pending_ == 0) done_.notify_one();
        }
    }

    unsigned threads_ = 1;
    std::vector<std::thread> workers_;
    std::mutex mutex_;
    std::condition_variable wake_, done_;
    void* context_ = nullptr;  // the caller's function object, called through call_
    void (*call_)(void*, std::size_t) = nullptr;
    std::size_t count_ = 0, parts_ = 1, pending_ = 0, generation_ = 0;
    bool quit_ = false;
};

}  // namespace tearables::detail
