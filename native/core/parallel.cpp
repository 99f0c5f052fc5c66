// parallel.cpp: see parallel.h.
#include "core/parallel.h"

#include <algorithm>
#include <atomic>
#include <exception>
#include <mutex>
#include <stdexcept>
#include <thread>

#include <oneapi/tbb/task_arena.h>
#include <oneapi/tbb/task_group.h>

namespace airlight {

void run_parallel(int n, int n_threads, const std::function<void(int)>& work,
                  const std::function<void(int)>& on_progress) {
    if (n <= 0) return;
    std::atomic<int> next{0};
    std::atomic<bool> stop{false};
    std::atomic<int> done{0};
    std::mutex mutex;
    std::exception_ptr error;
    auto fail = [&](std::exception_ptr e) {
        std::lock_guard<std::mutex> lock(mutex);
        if (!error) error = e;
        stop = true;
    };
    // Takes items until none is left or stop; _after_ runs after each completed item.
    auto take = [&](auto&& after) {
        while (!stop.load(std::memory_order_relaxed)) {
            const int i = next.fetch_add(1);
            if (i >= n) return;
            work(i);
            done.fetch_add(1);
            after();
        }
    };
    auto worker = [&]() {
        try {
            take([] {});
        } catch (...) {
            fail(std::current_exception());
        }
    };
    // oneTBB's thread pool (kept between calls) in an arena of n_threads: n_threads - 1
    // tasks take items, the calling thread takes items too and reports progress.
    n_threads = std::max(1, std::min(n_threads, n));
    const int report_every = std::max(1, n / 128);
    int reported = 0;
    oneapi::tbb::task_arena arena(n_threads);
    arena.execute([&] {
        oneapi::tbb::task_group group;
        for (int t = 1; t < n_threads; ++t) group.run(worker);
        try {
            take([&] {
                const int d = done.load(std::memory_order_relaxed);
                if (d - reported >= report_every) on_progress(reported = d);
            });
        } catch (...) {
            fail(std::current_exception());
        }
        group.wait();
    });
    if (error) std::rethrow_exception(error);
    on_progress(n);
}

void parallel_for(int n, int n_threads, const std::function<void(int)>& work) {
    run_parallel(n, n_threads, work, [](int) {});
}

std::string thread_count_error(int threads) {
    return "threads must be in [0, " + std::to_string(kMaxThreads) + "] (0: every hardware thread), got " +
           std::to_string(threads);
}

int resolve_threads(int threads) {
    if (threads < 0 || threads > kMaxThreads) throw std::invalid_argument(thread_count_error(threads));
    const int n = threads > 0 ? threads : int(std::thread::hardware_concurrency());
    return std::max(1, n);
}

}  // namespace airlight
