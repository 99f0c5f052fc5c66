"""Which native model computes the fog: the user's choice, or the cheapest one whose
measured error meets the accuracy target (`scene.airlight.model == 'AUTO'`).

The figures are measurements, not guesses; each names where it was measured:
- max_error: the worst relative error of the model's airlight against the quadrature
  reference (per light and pixel), from native/homogeneous/sun05_test.cpp's randomized sweep
  and special_f.cpp's table measurements (table path: max 1.9e-3, p99 5e-4); for biri06
  from native/homogeneous/biri06_test.cpp's sweep against the phase-aware quadrature
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
from collections import namedtuple

import numpy as np

from . import light_bounds, scene_description
from .names import (AREA_CELL, AREA_INTENSITY, MODEL_NAMES, SUPPORTED_LIGHT_TYPES, area_cell, is_isotropic,
                    native_phase)

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
# sun05's table choices (scene.airlight.table_resolution, table_interpolation): worst
# per-ray airlight error against the exact-F model, measured over 20000 random rays by
# native/homogeneous/sun05_nearest_test.cpp (AirlightErrorAgainstExactF). model_error takes the
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
PHASE_MODELS = ("biri06", "pegoraro10", "quadrature")
ISOTROPIC_ONLY = ("sun05", "sun05_exact")


def model_error(name, settings):
    """Measured max relative error of model _name_ for the settings' phase."""
    error = MEASURED[name][1]
    if name == "sun05":
        error = max(error, SUN05_TABLE_ERROR[_table_choice(settings)])
    if (name == "biri06" and settings.phase == 'HENYEY_GREENSTEIN'
            and abs(settings.anisotropy) >= BIRI06_NARROW_LOBE_G):
        error = BIRI06_NARROW_LOBE_ERROR
    if name == "pegoraro10" and settings.phase == 'HENYEY_GREENSTEIN' and settings.anisotropy != 0.0:
        error = PEGORARO10_HG_ERROR if abs(settings.anisotropy) <= PEGORARO10_MAX_G else math.inf
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


# Fog objects at reduced resolution (scene.airlight.gaussian_resolution, splat.h): max
# relative error of the Airlight and Transmittance passes against the full-resolution bake
# at 1920x1080, the worst over benchmarks/bench_rbf.py's scenes (34 broad blobs x 3 lights,
# 3000 blobs x 1 light, walls cutting the cloud). The error is the bilinear interpolation of
# smooth terms over 2 or 4 pixels: it grows with a pixel's size (REFERENCE_PIXEL_ANGLE
# below) and with fog noise.
# (Quarter: 0.502 % on the transmittance since its cull spheres are sized for 1e-5,
# GaussianSplat::kReducedCullEps; 0.526 % since broad blobs are interpolated from the far-field
# grids, splat.h, whose tolerance at Half is tighter to keep Half at 0.099 %.)
GAUSSIAN_RESOLUTION_ERROR = {'FULL': 0.0, 'HALF': 1.0e-3, 'QUARTER': 5.3e-3}
# The same with fog noise (noise_amplitude 0.4, noise_scale 1 m, the 34 and 3000 scenes;
# the noise is interpolated too): max 1.2 % (Half) and 5.8 % (Quarter) on the transmittance.
# More noise (larger amplitude, smaller scale) errs more.
GAUSSIAN_RESOLUTION_ERROR_NOISE = {'FULL': 0.0, 'HALF': 1.2e-2, 'QUARTER': 5.8e-2}
_RESOLUTIONS = ('QUARTER', 'HALF', 'FULL')  # coarse to fine
# Those errors are the bilinear interpolation's over 2 or 4 pixels, measured at 1920x1080
# with a 60-degree horizontal field of view (a pixel at the centre spans this angle). They
# grow as the square of a pixel's angle: the same scenes at lower render resolutions
# (bench_rbf.py --width W --height H --resolutions full,half,quarter; max over the scenes of
# the max transmittance error, which dominates) erred 3.75x (Quarter; Half 3.9x) at
# 960x540, 13.3x (14x) at 480x270 and 28.9x (32x) at 320x180, against (angle ratio)^2 =
# 4, 16 and 36 (the largest: Quarter 15.2 %, Half 3.16 % at 320x180, against 19.1 % and
# 3.6 % so scaled). Larger pixels (lower resolutions, wider lenses) scale the table by that
# square; smaller ones keep it.
REFERENCE_PIXEL_ANGLE = 2.0 * math.tan(math.radians(30.0)) / 1920.0


def pixel_angle(projection, width):
    """Angle of a pixel at the image centre for a perspective _projection_ (4x4, OpenGL
    convention, as scene_export exports it) _width_ pixels wide; None for orthographic ones
    (fog objects are not baked at reduced resolution there)."""
    if projection[3][2] == 0.0 or projection[0][0] == 0.0 or width < 1:
        return None
    return 2.0 / (abs(projection[0][0]) * width)


def gaussian_resolution_error(name, settings, pixel_angle=None):
    """Max relative error of fog objects at resolution _name_ against Full: the measured
    1080p figure, scaled by the square of _pixel_angle_ (radians at the image centre; None:
    the reference) over REFERENCE_PIXEL_ANGLE when that is larger."""
    noisy = getattr(settings, "noise_amplitude", 0.0) > 0.0
    error = (GAUSSIAN_RESOLUTION_ERROR_NOISE if noisy else GAUSSIAN_RESOLUTION_ERROR)[name]
    if pixel_angle is not None:
        error *= max(1.0, (pixel_angle / REFERENCE_PIXEL_ANGLE) ** 2)
    return error


def gaussian_resolution(settings, pixel_angle=None):
    """`_native.bake`'s gaussian_resolution ("full", "half", "quarter"): the user's choice;
    with the Automatic model the coarsest one, no coarser than that choice, whose error
    (gaussian_resolution_error at the render's _pixel_angle_) meets the accuracy target."""
    choice = getattr(settings, "gaussian_resolution", 'FULL')
    if settings.model == 'AUTO':
        target = settings.accuracy / 100.0
        for name in _RESOLUTIONS[_RESOLUTIONS.index(choice):]:
            if gaussian_resolution_error(name, settings, pixel_angle) <= target:
                choice = name
                break
    return choice.lower()


# The refinement's largest target (`_native.bake` takes gaussian_accuracy in [0, 1)).
GAUSSIAN_ACCURACY_MAX = 0.5


def gaussian_accuracy(settings):
    """`_native.bake`'s gaussian_accuracy: with the Automatic model its accuracy target, so that
    fog objects get Fogshop's approximation where its error bound meets the target and exact
    terms where it does not (gaussian/refine.h); 0 (Fogshop alone) with an explicit model or
    with noise (the refinement integrates the smooth Gaussians, not the noise)."""
    if settings.model != 'AUTO' or getattr(settings, "noise_amplitude", 0.0) > 0.0:
        return 0.0
    return min(settings.accuracy / 100.0, GAUSSIAN_ACCURACY_MAX)


# The default skip tolerance of a light's Radius (`_native.bake`'s light_size_tolerance),
# Automatic's share of its accuracy target for it, and the largest (the skip test's expansion
# in r^2 / h^2 holds beyond 8.7 radii: measured 2.8 % off where 2 % was asked at 4.3 radii).
LIGHT_SIZE_TOLERANCE = 1e-3
LIGHT_SIZE_SHARE = 0.25
LIGHT_SIZE_TOLERANCE_MAX = 0.005


def light_size_tolerance(settings):
    """`_native.bake`'s light_size_tolerance: a light's Radius changes its airlight by less
    than this (relative) on the rays where the bake skips it. Automatic: a quarter of its
    accuracy target, at most LIGHT_SIZE_TOLERANCE_MAX (the reach, ~sqrt(0.75 / tol) radii,
    shrinks as the target loosens: 17 radii at 1 %, 55 at 0.1 %); an explicit model: the bake's
    default (27 radii)."""
    if settings.model != 'AUTO':
        return LIGHT_SIZE_TOLERANCE
    return min(LIGHT_SIZE_TOLERANCE_MAX, max(1e-5, LIGHT_SIZE_SHARE * settings.accuracy / 100.0))


# Soft Shadow Samples Automatic with an explicit model (whose Accuracy is not shown): the
# penumbrae are measured against this target.
SOFT_SHADOW_TARGET = 0.01


def soft_shadow_target(settings):
    """The relative error Soft Shadow Samples Automatic (0) measures its count against
    (penumbra.choose): the Accuracy target with the Automatic model, else SOFT_SHADOW_TARGET;
    None for an explicit count or without volumetric shadows."""
    if not getattr(settings, "volumetric_shadows", False) or getattr(settings, "shadow_samples", 1) != 0:
        return None
    return settings.accuracy / 100.0 if settings.model == 'AUTO' else SOFT_SHADOW_TARGET


def phase_problem(settings):
    """A message if the explicitly chosen model cannot take the fog's phase, else None."""
    if settings.model == 'AUTO' or is_isotropic(settings):
        return None
    name = MODEL_NAMES[settings.model]
    if name in ISOTROPIC_ONLY:
        return (f"{MEASURED[name][0]} handles isotropic fog only: use Biri 2006, "
                f"Pegoraro 2010, Quadrature or Automatic for this phase")
    if name == "hoffman02" and settings.phase != 'HENYEY_GREENSTEIN':
        return ("Hoffman-Preetham 2002 has its own Rayleigh part: its Mie haze is "
                "Henyey-Greenstein (set Phase to Henyey-Greenstein)")
    if name == "pegoraro10" and math.isinf(model_error(name, settings)):
        return (f"Pegoraro 2010 represents Henyey-Greenstein up to Anisotropy +-{PEGORARO10_MAX_G} "
                f"(Legendre order 96): use Biri 2006, Quadrature or Automatic for this lobe")
    return None


def choose(settings):
    """(native model name, label, expected max relative error) for these fog settings."""
    if settings.model == 'BASELINE':
        return BASELINE
    if settings.model == 'HOFFMAN02':
        return HOFFMAN02
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


# Hoffman & Preetham 2002 daylight (never chosen by Automatic: it is another medium, with
# Rayleigh scattering): exact single scattering of sun lamps in it (closed form of
# sunlight_layer.h per colour channel, held to 2e-5 against scipy by
# tests/native/test_bake_hoffman02.py); point and spot lights are left out of its fog.
HOFFMAN02 = ("hoffman02", "Hoffman-Preetham 2002 (daylight)", 2e-5)
# The constant-colour bar (never chosen by Automatic): its error depends on the scene.
BASELINE = ("baseline", "Baseline (constant colour)", math.inf)
# Lights that are not point lights get their own model (bake.cpp): spots Pegoraro 2010's
# closed form with the exact piecewise cone profile for model pegoraro10, and for the other
# non-quadrature models when the phase polynomial has order <= 8 (isotropic, Rayleigh, hazy
# Mie: there it costs about what the quadrature does), else the adaptive quadrature
# (kSpotRelTol = 1e-5); suns the closed form of sunlight_layer.h (exact; held to 1e-6 against
# quadrature by sunlight_layer_test.cpp) or, with the quadrature model, its quadrature (1e-8).
SPOT_MODEL = ("Quadrature (spot)", 1e-5)
SPOT_CLOSED_FORM_MODEL = ("Pegoraro 2010 (spot)", 1e-6)
# Phase polynomial orders of the closed form (pegoraro10.h): HG with g != 0 needs >= 15.
_PHASE_ORDER = {'RAYLEIGH': 2, 'MIE_HAZY': 8, 'MIE_MURKY': 32}


def spot_model(name, settings):
    """(label, error) of the model spot lights get with point-light model _name_."""
    if name == "quadrature":
        return SPOT_MODEL
    order = 0 if is_isotropic(settings) else _PHASE_ORDER.get(settings.phase, 99)
    if name == "pegoraro10" or order <= 8:
        return SPOT_CLOSED_FORM_MODEL
    return SPOT_MODEL
SUN_MODEL = ("Closed form (sun)", 1e-6)
SUN_QUADRATURE_MODEL = ("Quadrature (sun)", 1e-8)

# One row of light_plan: status 'fog' (baked), 'skipped' (Automatic: below the target),
# 'off' (Scatter in Fog off), 'unsupported' (type not in the bake); label/error: the model
# it gets and its measured max relative error; share: its upper bound over the fog
# brightness bound (light_bounds.py), the largest over the colour channels.
# shadow: 'shadowed' (volumetric shadows traced), 'clear' (Automatic: no caster near enough
# to matter), 'no shadow' (the light's Cast Shadow is off), 'off' (Volumetric Shadows off, no
# caster in the scene), '' for lights not in the fog.
LightRow = namedtuple("LightRow", "name type status label error share shadow", defaults=("",))


def plan_rows(settings, survey):
    """Per light of a scene_description.Survey (the scene's render-visible lights, not
    instanced ones): what the bake does with it, as LightRows. Cheap (no bake): the panel
    redraws it when settings change.

    With the Automatic model, lights whose airlight is rigorously below the accuracy target
    everywhere in frame are skipped (light_bounds.py says what is guaranteed); instanced
    lights are never skipped. Explicit models bake every participating light."""
    name, point_label, point_error = choose(settings)
    sigma = float(settings.density)
    albedo = np.array(settings.color, dtype=np.float64)
    phase, g = native_phase(settings)
    p_min, p_max = light_bounds.phase_range(phase, g)
    frame = survey.frame
    rows, fogged = [], []
    kinds, weights, positions, casts = [], [], [], []   # per fogged light: type, I0 or E (RGB), position, shadow
    for light in survey.lights:
        if light.type not in SUPPORTED_LIGHT_TYPES or not getattr(light, "supported", True):
            rows.append(LightRow(light.name, light.type, 'unsupported', "", math.nan, math.nan))
            continue
        if not light.participates:
            rows.append(LightRow(light.name, light.type, 'off', "", math.nan, math.nan))
            continue
        if name == "hoffman02" and light.type != 'SUN':
            rows.append(LightRow(light.name, light.type, 'unsupported', "", math.nan, math.nan))
            continue
        if name == "baseline":
            label, error = BASELINE[1], BASELINE[2]
        elif light.type == 'SUN':
            label, error = SUN_QUADRATURE_MODEL if name == "quadrature" else SUN_MODEL
        elif light.type in ('SPOT', 'AREA'):  # area lights bake as spots (scene_export.area_samples)
            label, error = spot_model(name, settings)
        else:
            label, error = point_label, point_error
        rows.append(LightRow(light.name, light.type, 'fog', label, error, math.nan))
        fogged.append(len(rows) - 1)
        # A point or spot light an IES profile shapes is bounded as an area light is: not as a point (its
        # profile can exceed its power's share), so it is never skipped nor left unshadowed.
        kinds.append('AREA' if getattr(light, "profiled", False) else light.type)
        weights.append(light.emission if light.type == 'SUN' else
                       light.emission * AREA_INTENSITY if light.type == 'AREA' else light.emission / (4.0 * math.pi))
        positions.append(light.position)
        casts.append(light.casts_shadow)
    if not fogged:
        return rows
    kinds = np.array(kinds)
    weights = np.array(weights, dtype=np.float64).reshape(-1, 3)
    positions = np.array(positions, dtype=np.float64).reshape(-1, 3)
    uppers, lowers = np.full(weights.shape, math.inf), np.zeros(weights.shape)
    sun = kinds == 'SUN'
    uppers[sun], lowers[sun] = light_bounds.sun_bounds(weights[sun], sigma, albedo, p_min, p_max,
                                                       bool(settings.use_fog_top))
    if frame is not None and np.any(~sun):
        uppers[~sun], lowers[~sun] = light_bounds.point_bounds(
            frame, positions[~sun], weights[~sun], sigma, albedo, p_min, p_max, spot=kinds[~sun] != 'POINT')
    # An area light is no point: its bound is not the point's near it, so it is never skipped.
    area = kinds == 'AREA'
    uppers[area], lowers[area] = math.inf, 0.0
    skip = np.zeros(len(fogged), dtype=bool)
    # The bounds are those of the homogeneous fog: a light they rate faint can still light a
    # dense fog object (Gaussians) brightly, so Automatic skips no light when there is one.
    if settings.model == 'AUTO' and frame is not None and sigma > 0.0 and not survey.fog_objects:
        skip = light_bounds.skip_faint(uppers, lowers, settings.accuracy / 100.0)
    total_lower = lowers.sum(axis=0)
    with np.errstate(divide='ignore', invalid='ignore'):
        shares = np.max(np.where(uppers > 0.0, uppers / total_lower, 0.0), axis=1)
    for k, i in enumerate(fogged):
        rows[i] = rows[i]._replace(share=float(shares[k]), status='skipped' if skip[k] else 'fog')
    spent = uppers[skip].sum(axis=0) if np.any(skip) else np.zeros(3)
    shadows = shadow_states(settings, survey, kinds, weights, positions, np.array(casts, dtype=bool), albedo,
                            sigma, p_max, lowers, spent)
    for k, i in enumerate(fogged):
        if rows[i].status == 'fog':
            rows[i] = rows[i]._replace(shadow=shadows[k])
    return rows


def shadows_baked(settings, survey):
    """Whether the bake traces volumetric shadows: Volumetric Shadows on and a caster in the
    scene."""
    return bool(getattr(settings, "volumetric_shadows", False)) and bool(survey.casters)


def shadow_states(settings, survey, kinds, weights, positions, casts, albedo, sigma, p_max, lowers, spent):
    """Per fogged light of plan_rows: its LightRow.shadow. Automatic leaves unshadowed the
    point and spot lights whose shadows can darken no pixel by more than what the accuracy
    target leaves after the skipped lights (_spent_: their upper bounds; light_bounds.
    shadow_bounds against the fog brightness bound, as skip_faint); suns are shadowed
    wherever there is a caster (their light does not fall off)."""
    n = len(kinds)
    if not shadows_baked(settings, survey):
        return ['off'] * n
    states = np.where(casts, 'shadowed', 'no shadow').astype(object)
    # Every model shadows every light in Gaussian fog too; the brightness bound behind 'clear'
    # is the uniform fog's: none with fog objects.
    if not survey.fog_objects and settings.model == 'AUTO' and sigma > 0.0:
        positional = (kinds != 'SUN') & (kinds != 'AREA') & casts
        if np.any(positional):
            uppers = light_bounds.shadow_bounds(positions[positional], weights[positional], sigma, albedo, p_max,
                                                survey.casters)
            clear = light_bounds.skip_faint(uppers, lowers, settings.accuracy / 100.0, spent)
            states[np.flatnonzero(positional)[clear]] = 'clear'
    return [str(x) for x in states]


def light_plan(scene, depsgraph=None, view_layer=None):
    """plan_rows of _scene_'s lights (scene_description.survey: in _view_layer_, placed as
    _depsgraph_ evaluates them; without one as the objects are, for the panel)."""
    return plan_rows(scene.airlight, scene_description.survey(scene, depsgraph, view_layer))


# What the bake does with a scene's lights: the native model, the names of the lights
# Automatic skips (applied to the lights the depsgraph does not instance), and whether the
# model is the daylight one (sun lamps only).
# _unshadowed_: the scene's lights left without volumetric shadows (Automatic's clear ones;
# instanced lights keep their Cast Shadow); _shadows_: Volumetric Shadows on.
# _area_cell_: the sample cell of area lights (names.area_cell); _accuracy_: the accuracy target
# as a fraction (IES profiles are fitted to it).
Plan = namedtuple("Plan", "model skipped daylight shadows unshadowed area_cell accuracy",
                  defaults=(False, frozenset(), AREA_CELL, 0.01))


def plan(settings, survey):
    """The Plan for these fog settings and a scene_description.Survey of the scene."""
    name = choose(settings)[0]
    rows = plan_rows(settings, survey)
    skipped = frozenset()
    if settings.model == 'AUTO':
        skipped = frozenset(row.name for row in rows if row.status == 'skipped')
    shadows = shadows_baked(settings, survey)
    unshadowed = frozenset(row.name for row in rows if row.shadow == 'clear')
    return Plan(name, skipped, name == "hoffman02", shadows, unshadowed, area_cell(settings),
                settings.accuracy / 100.0)


def skipped_lights(scene, depsgraph=None):
    """Names of the lights light_plan skips (empty unless the model is Automatic)."""
    if scene.airlight.model != 'AUTO':
        return set()
    return {row.name for row in light_plan(scene, depsgraph) if row.status == 'skipped'}
