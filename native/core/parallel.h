// parallel.h: the kernels' parallel loop over work items.
#pragma once

#include <functional>
#include <string>

namespace airlight {

// Runs _work(i)_ for i in [0, n) on _n_threads_ threads (oneTBB's pool) that take items
// from an atomic counter, in index order (callers sort costly items first). The calling
// thread is one of them rather than a waiter: on 2 cores a third thread waking every
// n / 128 items preempted a worker each time (~3 % of a Gaussian bake in reschedules).
// A caller at a lowered priority (Linux: a nice value above 0, per thread) gets threads of
// its own instead of the pool's, which inherit its priority: its work then gives way to the
// threads it gives way to (the add-on's bake beside a render engine, render.py), where the
// pool's would compete with them at the normal one.
// Between its own items it calls _on_progress(done)_ once every n / 128 completions and at
// the end; if that throws (cancel) or any item throws, the others stop taking items and
// the exception propagates once they have finished.
void run_parallel(int n, int n_threads, const std::function<void(int)>& work,
                  const std::function<void(int)>& on_progress);

// run_parallel without progress.
void parallel_for(int n, int n_threads, const std::function<void(int)>& work);

// The most worker threads a caller may ask for: far above any machine this runs on, low
// enough that a typo (threads=100000) is refused instead of creating a huge task arena.
inline constexpr int kMaxThreads = 1024;

// _threads_ as the bake's settings give it (0: every hardware thread), at least 1. Throws
// std::invalid_argument for threads < 0 or > kMaxThreads (thread_count_error's message).
int resolve_threads(int threads);
// The message for a thread count outside [0, kMaxThreads].
std::string thread_count_error(int threads);

}  // namespace airlight
