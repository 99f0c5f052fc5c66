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
# The bake's cull tolerance (RbfMedium::kDefaultCullEps): its cull radii scale the noise.
BAKE_CULL_EPS = 1e-7
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


def _factors_from_native(native, fast, centres, scales, amplitudes, beta0, eye, lights, data_key):
    """Branch wt-rbf's `rbf_preview_factors`: optical depths T(v, b_i), T(s, b_i) (beta0
    included) and Gaussian i's own parts, and C_sv; f1 leaves the own parts out (as the
    bake's constructor). After a view change with the same Gaussians and lights only the
    eye side is asked for (no lights) and C_sv comes from L segments of a cached medium."""
    a = np.asarray(scales, np.float64)
    c = np.asarray(amplitudes, np.float64)
    eye = np.asarray(eye, np.float64).reshape(3)
    key = None if data_key is None else ("native", data_key, float(beta0), tuple(map(tuple, lights.tolist())))
    if key is not None and _light_side["key"] == key:
        out = fast(centres, a, c, float(beta0), eye, np.zeros((0, 3)))
        Ts = _light_side["Ts"]
        medium = _light_side["medium"]
        if medium is None:
            medium = _light_side["medium"] = native.RbfMedium(centres, a, c, beta0=float(beta0))
        D = np.linalg.norm(lights - eye, axis=1)
        T = medium.optical_depth(lights, np.broadcast_to(eye, lights.shape).copy())
        Csv = np.where(D > 0.0, np.exp(-np.maximum(T - beta0 * D, 0.0)), 1.0)
    else:
        out = fast(centres, a, c, float(beta0), eye, lights)
        Ts = np.asarray(out["T_sb"], np.float64) - np.asarray(out["own_sb"], np.float64)
        Csv = np.asarray(out["C_sv"], np.float64)
        if key is not None:
            _light_side.update(key=key, Ts=Ts, medium=None)
    Tv = np.asarray(out["T_vb"], np.float64) - np.asarray(out["own_vb"], np.float64)
    f1 = np.exp(-(np.maximum(Ts, 0.0) + np.maximum(Tv, 0.0)[None, :]))
    return f1.reshape(len(lights), -1), Csv


def fogshop_factors(native, centres, scales, amplitudes, beta0, eye, lights, data_key=None):
    """(f1 (L, n), C_sv (L,)) of Fogshop's per-(light, Gaussian) precomputation at the
    viewpoint _eye_. `_native.rbf_preview_factors` (branch wt-rbf: dict T_vb, own_vb,
    T_sb, own_sb, C_sv, ...) is used when the module has it; else the RbfMedium optical
    depths (with the light side cached across view changes under _data_key_)."""
    centres = np.ascontiguousarray(np.asarray(centres, np.float64).reshape(-1, 3))
    lights = np.asarray(lights, np.float64).reshape(-1, 3)
    if len(lights) == 0 or len(scales) == 0:
        return np.zeros((len(lights), len(scales))), np.ones(len(lights))
    fast = getattr(native, "rbf_preview_factors", None)
    if fast is not None:
        return _factors_from_native(native, fast, centres, scales, amplitudes, beta0, eye, lights, data_key)
    return _factors_from_optical_depth(native, centres, scales, amplitudes, beta0, eye, lights, data_key)


def ndc_bounds(centres, radii, persp):
    """NDC bounds (lo (n, 2), hi (n, 2)) of the projected cull spheres (centre, R) seen
    through the 4x4 _persp_ (projection @ view, row-major), and a mask of the visible
    ones: the formula of shaders/rbf_splat_vert.glsl in float64 (the planes x_ndc = k
    through the eye tangent to the sphere); (-1, 1) where the sphere reaches the eye
    plane, invisible where it lies wholly behind the eye or R = 0."""
    P = np.asarray(persp, np.float64).reshape(4, 4)
    b = np.asarray(centres, np.float64).reshape(-1, 3)
    R2 = np.asarray(radii, np.float64) ** 2
    r3 = P[3]
    bw = b @ r3[:3] + r3[3]
    A = bw * bw - R2 * np.dot(r3[:3], r3[:3])
    finite = (A > 1e-12 * bw * bw) & (bw > 0.0)
    lo = np.full((len(b), 2), -1.0)
    hi = np.full((len(b), 2), 1.0)
    with np.errstate(divide='ignore', invalid='ignore'):
        for axis in range(2):
            r = P[axis]
            a = b @ r[:3] + r[3]
            Bh = a * bw - R2 * np.dot(r[:3], r3[:3])
            C = a * a - R2 * np.dot(r[:3], r[:3])
            root = np.sqrt(np.maximum(Bh * Bh - A * C, 0.0))
            lo[:, axis] = np.where(finite, (Bh - root) / A, -1.0)
            hi[:, axis] = np.where(finite, (Bh + root) / A, 1.0)
    visible = (np.asarray(radii) > 0.0) & ~(~finite & (bw < 0.0) & (A > 0.0))
    lo = np.maximum(lo, -1.0)
    hi = np.minimum(hi, 1.0)
    visible &= (lo < hi).all(axis=1)
    return lo, hi, visible


def tile_lists(centres, radii, persp, size, scale, tile):
    """Per-tile Gaussian lists of the tile pass (shaders/rbf_tiles_frag.glsl): the splat
    target has ceil(size / scale) texels, texel q standing for the full-resolution pixel
    q scale + scale // 2 (clamped to the image); a tile is _tile_ x _tile_ texels. Each
    Gaussian goes to every tile that its cull sphere's screen bounds (`ndc_bounds`, one
    texel of margin) touch. Returns (first (ty, tx) int64, count (ty, tx) int64, entries
    (m,) int64 Gaussian indices, ascending within a tile)."""
    W, H = (int(v) for v in size)
    S = int(scale)
    lw, lh = -(-W // S), -(-H // S)
    tx_n, ty_n = -(-lw // tile), -(-lh // tile)
    lo, hi, vis = ndc_bounds(centres, radii, persp)
    full = np.array([W, H], np.float64)
    # Continuous full-resolution pixel coordinates of the bounds -> texel ranges.
    X_lo = (lo + 1.0) * 0.5 * full
    X_hi = (hi + 1.0) * 0.5 * full
    off = 0.5 + S // 2
    q_lo = np.floor((X_lo - off) / S) - 1.0
    q_hi = np.ceil((X_hi - off) / S) + 1.0
    q_max = np.array([lw - 1, lh - 1], np.float64)
    vis &= (q_hi >= 0.0).all(axis=1) & (q_lo <= q_max).all(axis=1)
    q_lo = np.clip(q_lo, 0.0, q_max).astype(np.int64)
    q_hi = np.clip(q_hi, 0.0, q_max).astype(np.int64)
    t_lo, t_hi = q_lo // tile, q_hi // tile
    gid = np.nonzero(vis)[0]
    w = t_hi[gid, 0] - t_lo[gid, 0] + 1
    h = t_hi[gid, 1] - t_lo[gid, 1] + 1
    sizes = w * h
    total = int(sizes.sum())
    starts = np.cumsum(sizes) - sizes
    g = np.repeat(np.arange(len(gid)), sizes)
    k = np.arange(total, dtype=np.int64) - np.repeat(starts, sizes)
    tx = t_lo[gid, 0][g] + k % w[g]
    ty = t_lo[gid, 1][g] + k // w[g]
    key = ty * tx_n + tx
    order = np.argsort(key, kind='stable')
    entries = gid[g[order]]
    count = np.bincount(key, minlength=tx_n * ty_n)
    first = np.cumsum(count) - count
    return first.reshape(ty_n, tx_n), count.reshape(ty_n, tx_n), entries


class GaussianFog:
    """GPU side of the Gaussian fog for one set of Gaussians: the data textures, the
    batch, the factors and the tile lists, rebuilt only when an input changes (`update`,
    `update_tiles`)."""

    def __init__(self):
        self.key = None          # (data id, beta0, eye, lights) the factors belong to
        self.data_key = None     # id of the Gaussian arrays the textures hold
        self.count = 0
        self.batch = None
        self.batch_count = -1
        self.gauss_tex = None
        self.f1_tex = None
        self.Csv = None
        self.radii = None
        self.centres = None
        self.factor_ms = None    # duration of the last factor computation
        self.tiles_key = None
        self.tile_tex = None     # (tile_index, tile_list) textures
        self.tile_pairs = 0      # (tile, Gaussian) entries of the last tile lists
        self.tiles_ms = None     # duration of the last tile-list build (CPU + upload)
        self.tiles_batch = None

    def update(self, native, shader, gaussians, beta0, eye, lights):
        """Makes textures/batch/factors current; _gaussians_ = dict(centres, scales,
        amplitudes, key, optionally colors (n, 3) per-Gaussian albedo or None) where
        _key_ changes whenever the arrays do."""
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
            centres = np.asarray(gaussians["centres"], np.float64).reshape(-1, 3)
            radii = cull_radii(gaussians["scales"], gaussians["amplitudes"])
            # The noise's per-Gaussian scale R_bake / |b - eye| (rbf_splat.h), as the bake.
            dist = np.linalg.norm(centres - np.asarray(eye, np.float64), axis=1)
            bake_radii = cull_radii(gaussians["scales"], gaussians["amplitudes"], BAKE_CULL_EPS)
            with np.errstate(divide='ignore', invalid='ignore'):
                noise_radii = np.where(dist > 0.0, bake_radii / dist, 0.0)
            self.gauss_tex, self.f1_tex = gs.rbf_data_textures(
                centres, gaussians["scales"], gaussians["amplitudes"], radii, f1,
                albedo=gaussians.get("colors"), noise_radii=noise_radii)
            self.radii = radii
            self.centres = centres
            self.key = key
            self.tiles_key = None
            self.count = n
            self.factor_ms = (time.perf_counter() - t0) * 1e3
        if shader is not None and self.batch_count != n:
            self.batch = gs.rbf_splat_batch(shader, n)
            self.batch_count = n

    def update_tiles(self, persp, size, scale):
        """Makes the tile lists current for the view _persp_ (4x4) at _size_ and _scale_."""
        import time
        from . import gpu_shaders as gs
        P = np.asarray(persp, np.float64).reshape(4, 4)
        key = (self.key, tuple(P.ravel().tolist()), tuple(size), int(scale))
        if key != self.tiles_key:
            t0 = time.perf_counter()
            first, count, entries = tile_lists(self.centres, self.radii, P, size, scale, gs.RBF_TILE)
            self.tile_tex = gs.rbf_tile_textures(first, count, entries)
            self.tile_pairs = len(entries)
            self.tiles_key = key
            self.tiles_ms = (time.perf_counter() - t0) * 1e3
