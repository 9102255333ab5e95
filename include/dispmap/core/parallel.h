#pragma once
// All cores for the work that is parallel in nature (oneTBB), with results that do not depend
// on the thread count.
//
// Every entry point that runs in parallel takes a thread count: 0 uses every core TBB allows
// (its default arena, so a tbb::global_control set by the application is respected), 1 runs
// the whole loop in the calling thread without starting a task (what the library did before it
// used more than one core), n uses at most n threads (a task arena of that size).
//
// The contract that makes the output bit-identical for every count: the body given a range of
// items writes only what those items own, and reads nothing another item of the same loop
// writes. Reductions are done by the caller over per-item (or per-chunk, with chunks fixed by
// the item count, never by the thread count) results in index order. The tests compare 1 and
// N threads bit for bit on every parallel entry point.
#include <algorithm>
#include <cstddef>
#include <memory>
#include <string>

#include <tbb/blocked_range.h>
#include <tbb/global_control.h>
#include <tbb/info.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include "dispmap/core/error.h"

namespace dispmap {

/// The largest thread count accepted (a guard against garbage, not a tuning limit).
inline constexpr int kMaxThreads = 4096;

/// Throws ArgumentError unless threads is in [0, kMaxThreads]; `what` names the option.
inline void checkThreads(int threads, const std::string& what) {
    if (threads < 0 || threads > kMaxThreads)
        throw ArgumentError(what + ": thread count " + std::to_string(threads) + " out of range [0, " +
                            std::to_string(kMaxThreads) + "] (0: all cores, 1: the calling thread only)");
}

/// The number of threads a count of 0 stands for here: what TBB's current arena allows, within
/// the application's tbb::global_control limit if it set one.
inline int allCores() {
    const std::size_t limit = tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism);
    const int arena = tbb::this_task_arena::max_concurrency();
    return limit > 0 && limit < static_cast<std::size_t>(arena) ? static_cast<int>(limit) : arena;
}

/// A thread count made usable: loops over index ranges on that many threads.
class Parallel {
  public:
    /// Throws ArgumentError for a count out of range (see checkThreads).
    explicit Parallel(int threads = 0, const std::string& what = "parallel") : threads_(threads) {
        checkThreads(threads, what);
        // An arena larger than the machine only makes TBB warn: the count is an upper bound.
        if (threads > 1) arena_ = std::make_unique<tbb::task_arena>(std::min(threads, tbb::info::default_concurrency()));
    }
    /// The threads the loops may use.
    int threads() const { return threads_ == 0 ? allCores() : arena_ ? arena_->max_concurrency() : 1; }
    bool serial() const { return threads() <= 1; }

    /// body(begin, end) over [0, n) in ranges of about `grain` items (at least 1), in any order
    /// and on any thread; serially, in one call body(0, n). The body must follow the contract
    /// above (disjoint writes), and may throw: an exception is rethrown here (which one, when
    /// several tasks throw, depends on the schedule: callers that name an item in an error
    /// catch per item and rethrow the first in order, as the tile build's sampling does).
    template <class Body> void ranges(std::size_t n, std::size_t grain, const Body& body) const {
        if (n == 0) return;
        if (serial() || n <= grain) {
            body(std::size_t{0}, n);
            return;
        }
        // Isolated: while it waits, the calling thread runs only this loop's tasks, never an
        // outer loop's (which could re-enter a std::call_once the caller is inside, as the lazy
        // auto-normal analysis is).
        const auto loop = [&] {
            tbb::this_task_arena::isolate([&] {
                tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, grain < 1 ? 1 : grain),
                                  [&](const tbb::blocked_range<std::size_t>& r) { body(r.begin(), r.end()); });
            });
        };
        if (arena_)
            arena_->execute(loop);
        else
            loop();
    }
    /// body(i) for every i in [0, n) (ranges of `grain` items).
    template <class Body> void each(std::size_t n, std::size_t grain, const Body& body) const {
        ranges(n, grain, [&](std::size_t b, std::size_t e) {
            for (std::size_t i = b; i < e; ++i) body(i);
        });
    }

  private:
    int threads_ = 0;
    std::unique_ptr<tbb::task_arena> arena_;
};

} // namespace dispmap
