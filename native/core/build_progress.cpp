// build_progress.cpp: see build_progress.h.
#include "core/build_progress.h"

#include <utility>

namespace airlight {

namespace {
thread_local BuildProgressScope* current_scope = nullptr;
constexpr auto kInterval = std::chrono::milliseconds(20);
}  // namespace

BuildProgressScope::BuildProgressScope(std::function<void()> check)
    : check_(std::move(check)), last_(std::chrono::steady_clock::now()), outer_(current_scope) {
    current_scope = this;
}

BuildProgressScope::~BuildProgressScope() { current_scope = outer_; }

void build_progress_check() {
    BuildProgressScope* scope = current_scope;
    if (!scope || !scope->check_) return;
    const auto now = std::chrono::steady_clock::now();
    if (now - scope->last_ < kInterval) return;
    scope->last_ = now;
    scope->check_();
}

}  // namespace airlight
