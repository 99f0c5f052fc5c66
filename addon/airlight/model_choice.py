"""Which native model computes the fog: the user's choice, or the cheapest one whose
measured error meets the accuracy target (`scene.airlight.model == 'AUTO'`).

The figures are measurements, not guesses; each names where it was measured:
- max_error: the worst relative error of the model's airlight against the quadrature
  reference (per light and pixel), from native/kernels/sun05_test.cpp's randomized sweep
  and special_f.cpp's table measurements (table path: max 1.9e-3, p99 5e-4); for biri06
  from native/kernels/biri06_test.cpp's sweep against the phase-aware quadrature
  (biri06.cpp: max 8.9e-4 for isotropic, Rayleigh, hazy/murky Mie and HG |g| < 0.95, up
  to 6e-3 for HG |g| >= 0.95, whose lobe is narrower than the table resolves);
- cost: time relative to the table model on the same 1920x1080 image, from
  benchmarks/bench_sun05.py (same run: sun05_exact ~98x, quadrature ~72x the table model) and for
  biri06 the bake's airlight pass, 1 light on 2 threads (150-240 ms vs 40 ms: ~5x).

The phase: the Sun 2005 models integrate the isotropic phase only (Henyey-Greenstein
with g = 0). For that case the Automatic choice is the one it has always been (biri06 is
not a candidate). An anisotropic phase needs a model that takes it: biri06 if its error
for that phase meets the target, else the phase-aware quadrature. An explicit Sun 2005
model with an anisotropic phase is reported by `phase_problem` (panel alert) and refused
by the bake (ValueError -> BakeError), never baked as isotropic fog.
"""

import math

from .properties import MODEL_NAMES, PHASE_NAMES

# native name -> (label, max relative error, relative cost)
MEASURED = {
    "sun05": ("Sun 2005 (table)", 1.9e-3, 1.0),
    "quadrature": ("Quadrature", 1e-8, 72.0),
    "sun05_exact": ("Sun 2005 (exact)", 1e-8, 98.0),
    "biri06": ("Biri 2006 (table)", 8.9e-4, 5.0),
}
# sun05's table choices (scene.airlight.table_resolution, table_interpolation): worst
# per-ray airlight error against the exact-F model, measured over 20000 random rays by
# native/kernels/sun05_nearest_test.cpp (AirlightErrorAgainstExactF). model_error takes the
# larger of this and MEASURED["sun05"] (the 256 bilinear default against quadrature).
# Nearest is no faster in the bake (benchmarks/bench_trade.py), so AUTO gains nothing from
# it; the entries make the shown error honest when a user picks a coarser table.
SUN05_TABLE_ERROR = {
    (64, 'NEAREST'): 9.26e-2, (128, 'NEAREST'): 4.31e-2,
    (256, 'NEAREST'): 2.22e-2, (512, 'NEAREST'): 1.16e-2,
    (64, 'BILINEAR'): 8.36e-3, (128, 'BILINEAR'): 3.11e-3,
    (256, 'BILINEAR'): 1.30e-3, (512, 'BILINEAR'): 6.17e-4,
}
# biri06's measured worst case for Henyey-Greenstein lobes with |g| >= 0.95.
BIRI06_NARROW_LOBE_ERROR = 6e-3
BIRI06_NARROW_LOBE_G = 0.95
# Models that integrate any phase function; the others are isotropic only.
PHASE_MODELS = ("biri06", "quadrature")
ISOTROPIC_ONLY = ("sun05", "sun05_exact")


def is_isotropic(settings):
    """True if the fog's phase is isotropic (Henyey-Greenstein with Anisotropy 0)."""
    return settings.phase == 'HENYEY_GREENSTEIN' and settings.anisotropy == 0.0


def native_phase(settings):
    """(phase, g) for `_native.bake`: ("isotropic", 0) or the phase with HG's g."""
    if is_isotropic(settings):
        return "isotropic", 0.0
    g = float(settings.anisotropy) if settings.phase == 'HENYEY_GREENSTEIN' else 0.0
    return PHASE_NAMES[settings.phase], g


def model_error(name, settings):
    """Measured max relative error of model _name_ for the settings' phase."""
    error = MEASURED[name][1]
    if name == "sun05":
        error = max(error, SUN05_TABLE_ERROR[_table_choice(settings)])
    if (name == "biri06" and settings.phase == 'HENYEY_GREENSTEIN'
            and abs(settings.anisotropy) >= BIRI06_NARROW_LOBE_G):
        error = BIRI06_NARROW_LOBE_ERROR
    return error


def _table_choice(settings):
    """(size, interpolation) of the Sun 2005 table the settings ask for."""
    return (int(getattr(settings, "table_resolution", '256')),
            getattr(settings, "table_interpolation", 'BILINEAR'))


def table_settings(settings):
    """`_native.bake` keywords for the Sun 2005 table. Other table models (biri06) keep
    the 256 x 256 bilinear table their error was measured with."""
    size, interp = _table_choice(settings)
    if choose(settings)[0] != "sun05":
        size, interp = 256, 'BILINEAR'
    return dict(table_size=size, table_interpolation=interp.lower())


def phase_problem(settings):
    """A message if the explicitly chosen model cannot take the fog's phase, else None."""
    if settings.model == 'AUTO' or is_isotropic(settings):
        return None
    name = MODEL_NAMES[settings.model]
    if name in ISOTROPIC_ONLY:
        return (f"{MEASURED[name][0]} handles isotropic fog only: use Biri 2006, "
                f"Quadrature or Automatic for this phase")
    return None


def choose(settings):
    """(native model name, label, expected max relative error) for these fog settings."""
    if settings.model != 'AUTO':
        name = MODEL_NAMES[settings.model]
    else:
        target = settings.accuracy / 100.0
        pool = [n for n in MEASURED if n != "biri06"] if is_isotropic(settings) else list(PHASE_MODELS)
        meeting = [n for n in pool if model_error(n, settings) <= target]
        # The accuracy property's minimum (0.01 %) is met by the exact models, so
        # `meeting` is never empty; fall back to the most accurate one regardless.
        candidates = meeting or [min(pool, key=lambda n: model_error(n, settings))]
        name = min(candidates, key=lambda n: MEASURED[n][2])
    label = MEASURED[name][0]
    error = model_error(name, settings)
    if name in ISOTROPIC_ONLY and not is_isotropic(settings):
        error = math.inf  # refused by the bake; never an error figure for the wrong phase
    return name, label, error
