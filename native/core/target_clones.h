// target_clones.h: AVX-512 / AVX2 / baseline versions of a vectorisable loop, picked at load
// time (GCC on x86-64; elsewhere one version). The clones round differently (FMA from AVX2 on):
// machines that pick different clones bake passes that differ in the last float bits
// (docs/architecture.md, "Determinism"). AIRLIGHT_NO_CLONES (cmake -DAIRLIGHT_NO_CLONES=ON)
// builds the baseline version only, here and in every other clone list of the kernels.
//   AIRLIGHT_ROW_CLONES: the clones alone (the bake's row loops).
//   AIRLIGHT_SIMD_CLONES: the clones with flatten, for the Gaussian fog's float kernels: every
//     call in the kernel (fast_erf.h's exp and erfc fits) is inlined whatever the translation
//     unit's inlining budget; a fit left as a call keeps the loop scalar, and the baseline
//     copy it calls lacks the clones' FMA (different rounding).
#pragma once

#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && !defined(AIRLIGHT_NO_CLONES)
#define AIRLIGHT_ROW_CLONES __attribute__((target_clones("arch=x86-64-v4", "arch=x86-64-v3", "default")))
#define AIRLIGHT_SIMD_CLONES \
    __attribute__((target_clones("arch=x86-64-v4", "arch=x86-64-v3", "default"), flatten))
#else
#define AIRLIGHT_ROW_CLONES
#define AIRLIGHT_SIMD_CLONES
#endif
