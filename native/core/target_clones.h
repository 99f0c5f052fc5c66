// target_clones.h: AVX-512 / AVX2 / baseline versions of a vectorisable loop, picked at load
// time (GCC on x86-64; elsewhere one version).
#pragma once

#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
#define AIRLIGHT_ROW_CLONES __attribute__((target_clones("arch=x86-64-v4", "arch=x86-64-v3", "default")))
#else
#define AIRLIGHT_ROW_CLONES
#endif
