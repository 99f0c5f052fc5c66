// build_progress.h: progress and cancel from inside long builds (the models' tables).
//
// A table of 256^2 to 4096^2 entries takes 0.03 to 15 s to build, inside a bake that reports
// progress only between its passes: the bar stood still and Esc went unseen. The bake installs
// a BuildProgressScope on its thread around its work; builders call build_progress_check()
// between rows. Calls from the installing thread reach the scope's callback (at most every
// 20 ms), which may throw (the bake's Cancelled) to stop the build; calls from other threads,
// or with no scope installed (a table built for a binding), do nothing. A builder that is
// stopped must leave nothing behind (the shared table caches keep only finished tables).
#pragma once

#include <chrono>
#include <functional>

namespace airlight {

class BuildProgressScope {
  public:
    explicit BuildProgressScope(std::function<void()> check);
    ~BuildProgressScope();
    BuildProgressScope(const BuildProgressScope&) = delete;
    BuildProgressScope& operator=(const BuildProgressScope&) = delete;

  private:
    friend void build_progress_check();
    std::function<void()> check_;
    std::chrono::steady_clock::time_point last_;
    BuildProgressScope* outer_;
};

// Calls the installing thread's scope callback if 20 ms have passed since its last call.
void build_progress_check();

}  // namespace airlight
