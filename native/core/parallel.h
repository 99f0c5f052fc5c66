// parallel.h: the kernels' parallel loop over work items.
#pragma once

#include <functional>

namespace airlight {

// Runs _work(i)_ for i in [0, n) on _n_threads_ threads that take items from an atomic
// counter: the calling thread is one of them (n_threads - 1 are started). Between its own
// items the calling thread calls _on_progress(done)_ once every n / 128 completions and at
// the end; if that throws (cancel) or any item throws, the others stop taking items and
// the exception propagates once they have finished.
// (The calling thread used to only wait on a condition variable, woken every n / 128
// items: on 2 cores that third thread preempted a worker at each wake-up, ~3 % of a
// Gaussian bake's samples in reschedule IPIs and futex calls.)
void run_parallel(int n, int n_threads, const std::function<void(int)>& work,
                  const std::function<void(int)>& on_progress);

// _threads_ as the bake's settings give it (0: every hardware thread), at least 1.
int resolve_threads(int threads);

}  // namespace airlight
