// thread_scratch.h: per-thread scratch buffers that the optimizer cannot re-look-up.
#pragma once

namespace airlight {

// The calling thread's instance of _T_ (a struct of scratch vectors, one type per use: two
// callers of the same type would share it). Through a call the optimizer does not inline:
// in a shared library (the Python module) every use of a thread_local inside a loop becomes a
// __tls_get_addr call, which GCC re-issues rather than keeping the address (measured: 3 % of a
// shadowed 1080p bake); the reference this returns stays in a register.
template <class T>
[[gnu::noinline]] T& thread_scratch() {
    thread_local T scratch;
    return scratch;
}

}  // namespace airlight
