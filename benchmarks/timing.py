"""The benchmarks' shared timer: the median wall time of repeated calls (the machines are
noisy, so every figure is a median). Plain Python, importable from /usr/bin/python3 scripts
and from the ones Blender runs (they put this folder on sys.path)."""

import statistics
import time


def median_seconds(fn, runs):
    """Median over _runs_ calls of fn() of its wall time, in seconds."""
    times = []
    for _ in range(runs):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def median_ms(fn, runs):
    """median_seconds in milliseconds."""
    return median_seconds(fn, runs) * 1e3
