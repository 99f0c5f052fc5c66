// parallel_test.cpp: run_parallel takes every item once, propagates a failure, and keeps a
// caller at a lowered priority (Linux: per thread) and its work there.
#include "core/parallel.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <functional>
#include <mutex>
#include <stdexcept>
#include <thread>
#include <vector>

#if defined(__linux__)
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>
#endif

namespace airlight {
namespace {

// Each item's count of visits after run_parallel on _threads_ threads; _also(i)_ runs on
// each visit.
std::vector<int> visits(int n, int threads, const std::function<void(int)>& also = [](int) {}) {
    std::vector<std::atomic<int>> count(static_cast<size_t>(n));
    parallel_for(n, threads, [&](int i) {
        count[static_cast<size_t>(i)].fetch_add(1);
        also(i);
    });
    std::vector<int> out;
    for (auto& c : count) out.push_back(c.load());
    return out;
}

TEST(Parallel, EveryItemOnce) {
    for (int threads : {1, 2, 7})
        for (int n : {0, 1, 5, 1000}) EXPECT_EQ(visits(n, threads), std::vector<int>(size_t(n), 1)) << threads;
}

TEST(Parallel, AFailureStopsTheLoopAndPropagates) {
    std::atomic<int> after{0};
    EXPECT_THROW(parallel_for(10000, 2,
                              [&](int i) {
                                  if (i == 10) throw std::runtime_error("item 10");
                                  // Items of some length: a process's first throw takes
                                  // ~1 ms, in which empty items would all have run.
                                  std::this_thread::sleep_for(std::chrono::microseconds(20));
                                  if (i > 5000) after.fetch_add(1);
                              }),
                 std::runtime_error);
    EXPECT_LT(after.load(), 4000);  // the others stopped taking items
}

#if defined(__linux__)
int own_nice() { return getpriority(PRIO_PROCESS, static_cast<id_t>(syscall(SYS_gettid))); }

TEST(Parallel, AYieldingCallersWorkKeepsItsPriority) {
    // A thread of its own lowers its priority (as the add-on's bake beside a render engine
    // does); every item then runs at that priority, on more than one thread, and each still
    // once. The process's other threads keep theirs.
    const int before = own_nice();
    std::mutex mutex;
    std::vector<int> nices;
    std::vector<std::thread::id> ids;
    std::vector<int> counts;
    std::thread caller([&] {
        ASSERT_EQ(setpriority(PRIO_PROCESS, static_cast<id_t>(syscall(SYS_gettid)), 19), 0);
        counts = visits(2000, 2, [&](int) {
            std::this_thread::sleep_for(std::chrono::microseconds(20));
            std::lock_guard<std::mutex> lock(mutex);
            nices.push_back(own_nice());
            ids.push_back(std::this_thread::get_id());
        });
    });
    caller.join();
    EXPECT_EQ(counts, std::vector<int>(2000, 1));
    for (int nice : nices) ASSERT_EQ(nice, 19);
    std::sort(ids.begin(), ids.end());
    EXPECT_GT(std::unique(ids.begin(), ids.end()) - ids.begin(), 1);  // still in parallel
    EXPECT_EQ(own_nice(), before);  // the test's own thread kept its priority
}
#endif

}  // namespace
}  // namespace airlight
