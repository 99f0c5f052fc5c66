// simd_clones.h: AIRLIGHT_SIMD_CLONES puts a vectorisable loop in AVX-512, AVX2 and baseline
// versions, picked at load time (GCC on x86-64; elsewhere one version), for the Gaussian
// fog's float kernels.
// flatten: every call in the kernel (fast_erf.h's exp and erfc fits) is inlined whatever the
// translation unit's inlining budget; a fit left as a call keeps the loop scalar, and the
// baseline copy it calls lacks the clones' FMA (different rounding).
#pragma once

#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && !defined(AIRLIGHT_NO_CLONES)
#define AIRLIGHT_SIMD_CLONES \
    __attribute__((target_clones("arch=x86-64-v4", "arch=x86-64-v3", "default"), flatten))
#else
#define AIRLIGHT_SIMD_CLONES
#endif
