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
  biri06 the bake's airlight pass, 1 light on 2 threads (150-240 ms vs 40 ms: ~5x);
- pegoraro10 (closed form, benchmarks/bench_pegoraro.py): max error vs quadrature 1.2e-11 for
  the exact polynomial phases (isotropic, Rayleigh, hazy/murky Mie); for Henyey-Greenstein,
  truncated at the order the bake picks (Legendre tail below 1e-6 of the lobe, at most 96),
  max 2.6e-7 for |g| <= 0.75 (g = 0.3, 0.6, 0.75 measured); beyond |g| ~ 0.78 order 96 is not
  enough (9.6e-2 at 0.9, negative values at 0.99) and the bake refuses it. Cost: ~1.5-5.3 us per evaluation
  vs 0.24 us for the table in the same run (order 0 to 32-41): 22x, the high-order figure.

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
    "pegoraro10": ("Pegoraro 2010 (closed form)", 1.2e-11, 22.0),
}
# pegoraro10 with Henyey-Greenstein: error at the bake's truncation order (bench_pegoraro.py);
# the bake refuses |g| above PEGORARO10_MAX_G (no order <= 96 meets its tolerance there).
PEGORARO10_HG_ERROR = 2.6e-7
PEGORARO10_MAX_G = 0.78
# biri06's measured worst case for Henyey-Greenstein lobes with |g| >= 0.95.
BIRI06_NARROW_LOBE_ERROR = 6e-3
BIRI06_NARROW_LOBE_G = 0.95
# Models that integrate any phase function; the others are isotropic only.
PHASE_MODELS = ("biri06", "pegoraro10", "quadrature")
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
    if (name == "biri06" and settings.phase == 'HENYEY_GREENSTEIN'
            and abs(settings.anisotropy) >= BIRI06_NARROW_LOBE_G):
        error = BIRI06_NARROW_LOBE_ERROR
    if name == "pegoraro10" and settings.phase == 'HENYEY_GREENSTEIN' and settings.anisotropy != 0.0:
        error = PEGORARO10_HG_ERROR if abs(settings.anisotropy) <= PEGORARO10_MAX_G else math.inf
    return error


def phase_problem(settings):
    """A message if the explicitly chosen model cannot take the fog's phase, else None."""
    if settings.model == 'AUTO' or is_isotropic(settings):
        return None
    name = MODEL_NAMES[settings.model]
    if name in ISOTROPIC_ONLY:
        return (f"{MEASURED[name][0]} handles isotropic fog only: use Biri 2006, "
                f"Pegoraro 2010, Quadrature or Automatic for this phase")
    if name == "pegoraro10" and math.isinf(model_error(name, settings)):
        return (f"Pegoraro 2010 represents Henyey-Greenstein up to Anisotropy +-{PEGORARO10_MAX_G} "
                f"(Legendre order 96): use Biri 2006, Quadrature or Automatic for this lobe")
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
