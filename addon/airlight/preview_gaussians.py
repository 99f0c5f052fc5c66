"""Gaussian fog (fog objects) in the viewport preview: the GPU pipeline of Fogshop
(Zhou et al. 2007) section 5, fed by the same Fogshop approximation the bake uses
(native/kernels/rbf_airlight.{h,cpp}).

Per frame (or per edit / view change, cached):
- natively, per (light, Gaussian): f1 = exp(-(T(s, b_i) + T(v, b_i)) without Gaussian i's
  own terms) and per light C_sv = exp(-(T(s, v) - beta0 |s - v|)) (`fogshop_factors`);
- per-Gaussian data (centre, scale, amplitude, cull radius) and f1 as float textures
  (`gpu_shaders.rbf_data_textures`), and one quad per Gaussian (`rbf_splat_batch`).
Per draw:
- the splat pass (shaders/rbf_splat_*.glsl): each Gaussian's quad covers the projected
  bounds of its cull sphere; per pixel the analytic line integrals (erf form, eq. 31) up
  to the pixel's surface and L_i = f0 f1 T_i (eq. 11) per light, added (ADDITIVE_PREMULT)
  into two full-resolution RGBA32F targets;
- the fog pass (fog_preview_frag.glsl with PREVIEW_GAUSSIANS) combines them with the
  homogeneous part (beta0 = scene density, scaled by C_sv per light) exactly as the bake's
  eval_rbf does: La = e^{T_near} (La_0 + e^{beta0 t0} sum_i (L_i(Dvp) - L_i(t0))),
  Tr = exp(-(beta0 (Dvp - t0) + sum_i T_i(t0, Dvp))).

Limits: the splat pass runs at full resolution (the preview's HALF/QUARTER scales fall
back to FULL while fog objects are visible); f1 and C_sv are set up at the view origin,
which for orthographic views is the view centre rather than each ray's own origin (the
bake sets orthographic rays up per ray), so orthographic previews of Gaussian fog are
approximate.
"""

import math

import numpy as np

# Per-Gaussian cull tolerance on the optical depth of the splat quads and of the
# fragment's cull test. The bake uses RbfMedium::kDefaultCullEps = 1e-7; the preview
# drops Gaussians that add < 1e-4 to a pixel's optical depth: their radii (and quads)
# shrink by ~25 % (area ~45 %) for a measured difference to the bake in test_09.
CULL_EPS = 1e-4
_SQRT_PI = math.sqrt(math.pi)


def cull_radii(scales, amplitudes, eps=CULL_EPS):
    """R_i = sqrt(ln(c_i sqrt(pi) / (a_i eps))) / a_i, 0 where the log is <= 0 (as
    native/kernels/rbf_medium.h): outside that sphere a segment integrates to < eps."""
    a = np.asarray(scales, np.float64)
    c = np.asarray(amplitudes, np.float64)
    with np.errstate(divide='ignore'):
        arg = np.log(np.where(c > 0.0, c * _SQRT_PI / (a * eps), 1.0))
    return np.where(arg > 0.0, np.sqrt(np.maximum(arg, 0.0)) / a, 0.0)


# The light-side optical depths T(s, b_i) of the last call, kept while the Gaussians,
# beta0 and the lights stay the same: moving the view then recomputes only T(v, b_i)
# and C_sv (one segment per Gaussian instead of 1 + L).
_light_side = {"key": None, "Ts": None, "medium": None}


def clear_cache():
    """Drops the cached light side (on file load / unregister)."""
    _light_side.update(key=None, Ts=None, medium=None)


def _factors_from_optical_depth(native, centres, scales, amplitudes, beta0, eye, lights, data_key=None):
    """f1 and C_sv with the RbfMedium binding: culled optical depths of the segments
    s -> b_i and v -> b_i, minus Gaussian i's own part T_i(p, b_i) = c sqrt(pi)/(2a)
    erf(a |b_i - p|) (the line ends at the centre), as RbfAirlightFogshop's constructor
    sums the medium without Gaussian i. _data_key_ (changes with the Gaussian arrays)
    lets the light side be reused across view changes."""
    n = len(scales)
    key = None if data_key is None else (data_key, float(beta0), tuple(map(tuple, np.asarray(lights).tolist())))
    reuse = key is not None and _light_side["key"] == key
    medium = _light_side["medium"] if reuse else native.RbfMedium(centres, scales, amplitudes,
                                                                   beta0=float(beta0))
    a = np.asarray(scales, np.float64)
    k = np.asarray(amplitudes, np.float64) * _SQRT_PI / (2.0 * a)
    eye = np.asarray(eye, np.float64).reshape(3)

    def depth_to_centres(p):
        p = np.asarray(p, np.float64).reshape(3)
        dist = np.linalg.norm(centres - p, axis=1)
        total = medium.optical_depth(np.broadcast_to(p, (n, 3)).copy(), centres)
        own = k * native.erf_diff(np.zeros(n), a * dist)
        return np.maximum(total - own, 0.0)

    Tv = depth_to_centres(eye)
    L = len(lights)
    Ts = _light_side["Ts"] if reuse else [depth_to_centres(s) for s in lights]
    if key is not None:
        _light_side.update(key=key, Ts=Ts, medium=medium)
    f1 = np.empty((L, n))
    Csv = np.ones(L)
    for l, s in enumerate(lights):
        f1[l] = np.exp(-(Ts[l] + Tv))
        s = np.asarray(s, np.float64)
        D = float(np.linalg.norm(s - eye))
        if D > 0.0:
            T = float(medium.optical_depth(s[None], eye[None])[0])
            Csv[l] = math.exp(-max(T - beta0 * D, 0.0))
    return f1, Csv


def fogshop_factors(native, centres, scales, amplitudes, beta0, eye, lights, data_key=None):
    """(f1 (L, n), C_sv (L,)) of Fogshop's per-(light, Gaussian) precomputation at the
    viewpoint _eye_. The one place to switch to `_native.rbf_preview_factors` (being added
    on another branch): it is used when present."""
    centres = np.ascontiguousarray(np.asarray(centres, np.float64).reshape(-1, 3))
    lights = np.asarray(lights, np.float64).reshape(-1, 3)
    if len(lights) == 0 or len(scales) == 0:
        return np.zeros((len(lights), len(scales))), np.ones(len(lights))
    fast = getattr(native, "rbf_preview_factors", None)
    if fast is not None:
        out = fast(centres, np.asarray(scales, np.float64), np.asarray(amplitudes, np.float64),
                   float(beta0), np.asarray(eye, np.float64), lights)
        return np.asarray(out["f1"], np.float64).reshape(len(lights), -1), np.asarray(out["Csv"], np.float64)
    return _factors_from_optical_depth(native, centres, scales, amplitudes, beta0, eye, lights, data_key)


class GaussianFog:
    """GPU side of the Gaussian fog for one set of Gaussians: the data textures, the
    batch and the factors, rebuilt only when an input changes (`update`)."""

    def __init__(self):
        self.key = None          # (data id, beta0, eye, lights) the factors belong to
        self.data_key = None     # id of the Gaussian arrays the textures hold
        self.count = 0
        self.batch = None
        self.batch_count = -1
        self.gauss_tex = None
        self.f1_tex = None
        self.Csv = None
        self.factor_ms = None    # duration of the last factor computation

    def update(self, native, shader, gaussians, beta0, eye, lights):
        """Makes textures/batch/factors current; _gaussians_ = dict(centres, scales,
        amplitudes, key) where _key_ changes whenever the arrays do."""
        import time
        from . import gpu_shaders as gs
        n = len(gaussians["scales"])
        lights = [tuple(float(x) for x in s) for s in lights]
        key = (gaussians["key"], float(beta0), tuple(float(x) for x in eye), tuple(lights))
        if key != self.key:
            t0 = time.perf_counter()
            f1, self.Csv = fogshop_factors(native, gaussians["centres"], gaussians["scales"],
                                           gaussians["amplitudes"], beta0, eye, lights,
                                           data_key=gaussians["key"])
            radii = cull_radii(gaussians["scales"], gaussians["amplitudes"])
            self.gauss_tex, self.f1_tex = gs.rbf_data_textures(
                gaussians["centres"], gaussians["scales"], gaussians["amplitudes"], radii, f1)
            self.key = key
            self.count = n
            self.factor_ms = (time.perf_counter() - t0) * 1e3
        if self.batch_count != n:
            self.batch = gs.rbf_splat_batch(shader, n)
            self.batch_count = n
