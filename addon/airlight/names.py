"""The names the add-on's modules share: the fog settings' enums and their native names,
the light types the bake scatters, and the names of the baked passes and light groups.

A leaf module (no bpy, nothing of the package): every other module may import it.
"""

import math

# Scene model enum -> name in _native.models(). AUTO is resolved by model_choice.py.
MODEL_NAMES = {
    'AUTO': "sun05",
    'SUN05': "sun05",
    'SUN05_EXACT': "sun05_exact",
    'QUADRATURE': "quadrature",
    'BIRI06': "biri06",
    'BASELINE': "baseline",
    'PEGORARO10': "pegoraro10",
    'HOFFMAN02': "hoffman02",
}

# Scene phase enum -> `_native.bake(phase=...)`; the anisotropy g applies to HG only.
PHASE_NAMES = {
    'HENYEY_GREENSTEIN': "hg",
    'RAYLEIGH': "rayleigh",
    'MIE_HAZY': "mie_hazy",
    'MIE_MURKY': "mie_murky",
}

# Light types the bake scatters; the others are listed in the UI as "not yet in fog".
SUPPORTED_LIGHT_TYPES = {'POINT', 'SPOT', 'SUN', 'AREA'}
# Cycles' area light: a one-sided Lambert emitter whose radiant intensity is C P / 4 cos(theta)
# about its -Z (kernel/light/area.h: radiance P / (4 A)).
AREA_INTENSITY = 0.25
# An area light bakes as spot samples on a grid of cells of about area_cell(settings) m, 1 to
# AREA_MAX_PER_AXIS per side (scene_export.area_samples). AREA_CELL is the cell for the
# explicit models; Automatic narrows it with the accuracy asked for: the mean error of the
# fog beyond the light's own image fell as 1 / samples on a 3 x 1 m light 2-10 m from the
# fog (tests/blender/test_cycles_area.py's scene: 8 samples 1.6 %, 12 1.15 %, 32 0.59 %,
# 48 0.37 %), so a cell of AREA_CELL sqrt(accuracy / AREA_CELL_ERROR).
AREA_CELL = 0.5
AREA_CELL_ERROR = 1.6   # %: the mean error measured with AREA_CELL
AREA_MAX_PER_AXIS = 8
# With a Spread s below 180 degrees each sample lights a cone of half-angle s / 2, and the
# error grew as (cell / s)^2: a 2 m disk, Spread 50 degrees, against the area integral
# (tests/blender/test_cycles_area.py's scene): 16 samples 9.9 %, 64 2.4 %, 256 0.59 %, 1024
# 0.17 %, 12x the 180 degrees' error at each count (0.84 %, 0.22 %, 0.06 %, 0.01 %). So the
# cell narrows by s / 180 degrees, up to AREA_MAX_PER_AXIS_SPREAD samples per side.
AREA_MAX_PER_AXIS_SPREAD = 16


def area_cell(settings):
    """The sample cell (m) of area lights with the full Spread for these fog settings."""
    if getattr(settings, "model", 'AUTO') != 'AUTO':
        return AREA_CELL
    accuracy = max(float(getattr(settings, "accuracy", 1.0)), 1e-3)
    return max(0.05, AREA_CELL * min(1.0, (accuracy / AREA_CELL_ERROR) ** 0.5))


def _spread_share(spread):
    """Spread / 180 degrees, in (0, 1]."""
    return min(1.0, max(float(spread), math.radians(1.0)) / math.pi)


def area_grid(size_x, size_y, cell=AREA_CELL, spread=math.pi):
    """(kx, ky): an area light's samples per side for its sizes along X and Y (m) and its
    Spread (rad): cells of _cell_ m, narrowed by the Spread's share of 180 degrees."""
    share = _spread_share(spread)
    most = AREA_MAX_PER_AXIS if share >= 1.0 else AREA_MAX_PER_AXIS_SPREAD
    return tuple(int(min(most, max(1, round(abs(float(s)) / (cell * share))))) for s in (size_x, size_y))


def area_error(size_x, size_y, cell=AREA_CELL, spread=math.pi):
    """The expected mean error (a fraction) of an area light's fog beyond its image for its
    sample grid (area_grid): AREA_CELL_ERROR at cells of AREA_CELL, as (cell / Spread share)^2."""
    kx, ky = area_grid(size_x, size_y, cell, spread)
    actual = max(abs(float(size_x)) / kx, abs(float(size_y)) / ky, 1e-9)
    return AREA_CELL_ERROR / 100.0 * (actual / AREA_CELL / _spread_share(spread)) ** 2


def is_isotropic(settings):
    """True if the fog's phase is isotropic (Henyey-Greenstein with Anisotropy 0)."""
    return settings.phase == 'HENYEY_GREENSTEIN' and settings.anisotropy == 0.0


def native_phase(settings):
    """(phase, g) for `_native.bake`: ("isotropic", 0) or the phase with HG's g."""
    if is_isotropic(settings):
        return "isotropic", 0.0
    g = float(settings.anisotropy) if settings.phase == 'HENYEY_GREENSTEIN' else 0.0
    return PHASE_NAMES[settings.phase], g


# EXR layout: channels "Fog.Airlight.R" ... Blender 3.4 reads "<layer>.<pass>.<chan>" as
# layer "Fog" with passes "Airlight" and "Transmittance", which the compositor Image
# node exposes as outputs of those names. (Without a layer prefix the passes also show,
# but in a nameless layer that RNA cannot represent.)
LAYER_PREFIX = "Fog."
PASS_AIRLIGHT = "Airlight"
# Per-light airlight passes (Light Passes): Airlight_<light name>, the name with only
# [A-Za-z0-9_] as the light groups' (surface.group_name); the World's glow as Airlight_World.
LIGHT_PASS_PREFIX = PASS_AIRLIGHT + "_"
PASS_AIRLIGHT_WORLD = LIGHT_PASS_PREFIX + "World"


def light_pass(object_name):
    """The per-light airlight pass of light object _object_name_."""
    import re
    return LIGHT_PASS_PREFIX + re.sub(r"[^A-Za-z0-9_]", "_", object_name)
PASS_TRANSMITTANCE = "Transmittance"
# Surface shading (surface.py): a Cycles light group fog_<light> per fogged light, whose
# pass Surface_<group> (attenuation - 1) the bake writes, the Lambert glow per unit DiffCol
# and the glossy glow per unit Glossy Color.
GROUP_PREFIX = "fog_"
PASS_PREFIX = "Surface_"
PASS_GLOW = "SurfaceGlow"
PASS_GLOSS = "SurfaceGloss"
# The World's light group when the environment glow is on (environment.py): its pass is
# scaled by the fog-aware environment irradiance ratio, like a light's by its attenuation.
WORLD_GROUP = GROUP_PREFIX + "world_environment"
