// parallel.cpp: see parallel.h.
#include "core/parallel.h"

#include <algorithm>
#include <atomic>
#include <exception>
#include <mutex>
#include <stdexcept>
#include <system_error>
#include <thread>
#include <vector>

#if defined(__linux__)
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <cerrno>
#endif

#include <oneapi/tbb/task_arena.h>
#include <oneapi/tbb/task_group.h>

namespace airlight {

namespace {

// Whether the calling thread runs at a lowered priority (a nice value above 0: Linux keeps
// one per thread), as Airlight's bake beside a render engine does (render.py).
bool caller_yields() {
#if defined(__linux__)
    errno = 0;
    const int nice = getpriority(PRIO_PROCESS, static_cast<id_t>(syscall(SYS_gettid)));
    return errno == 0 && nice > 0;
#else
    return false;
#endif
}

}  // namespace

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
    auto take_and_report = [&] {
        try {
            take([&] {
                const int d = done.load(std::memory_order_relaxed);
                if (d - reported >= report_every) on_progress(reported = d);
            });
        } catch (...) {
            fail(std::current_exception());
        }
    };
    if (n_threads > 1 && caller_yields()) {
        // A caller at a lowered priority keeps its work there: threads of its own, which
        // inherit its priority, instead of the pool's, which would compete at the normal
        // one with the threads it gives way to (a render engine's).
        std::vector<std::thread> threads;
        try {
            for (int t = 1; t < n_threads; ++t) threads.emplace_back(worker);
        } catch (const std::system_error&) {  // no thread to be had: fewer take the items
        }
        take_and_report();
        for (auto& thread : threads) thread.join();
    } else {
        oneapi::tbb::task_arena arena(n_threads);
        arena.execute([&] {
            oneapi::tbb::task_group group;
            for (int t = 1; t < n_threads; ++t) group.run(worker);
            take_and_report();
            group.wait();
        });
    }
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
