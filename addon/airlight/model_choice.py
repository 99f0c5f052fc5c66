"""Which native model computes the fog: the user's choice, or the cheapest one whose
measured error meets the accuracy target (`scene.airlight.model == 'AUTO'`).

The figures are measurements, not guesses; each names where it was measured:
- max_error: the worst relative error of the model's airlight against the quadrature
  reference (per light and pixel), from native/kernels/sun05_test.cpp's randomized sweep
  and special_f.cpp's table measurements (table path: max 1.9e-3, p99 5e-4);
- cost: time relative to the table model on the same 1920x1080 image, from
  benchmarks/bench_sun05.py (sun05_exact ~27x, quadrature ~20x the table model).
"""

from .properties import MODEL_NAMES

# native name -> (label, max relative error, relative cost)
MEASURED = {
    "sun05": ("Sun 2005 (table)", 1.9e-3, 1.0),
    "quadrature": ("Quadrature", 1e-8, 20.0),
    "sun05_exact": ("Sun 2005 (exact)", 1e-8, 27.0),
}


def choose(settings):
    """(native model name, label, expected max relative error) for these fog settings."""
    if settings.model != 'AUTO':
        name = MODEL_NAMES[settings.model]
    else:
        target = settings.accuracy / 100.0
        meeting = [n for n, (_, err, _) in MEASURED.items() if err <= target]
        # The accuracy property's minimum (0.01 %) is met by the exact models, so
        # `meeting` is never empty; fall back to the most accurate one regardless.
        candidates = meeting or [min(MEASURED, key=lambda n: MEASURED[n][1])]
        name = min(candidates, key=lambda n: MEASURED[n][2])
    label, error, _ = MEASURED[name]
    return name, label, error
