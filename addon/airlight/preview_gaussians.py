"""Gaussian fog (fog objects) in the viewport preview: the GPU pipeline of Fogshop
(Zhou et al. 2007) section 5, fed by the same Fogshop approximation the bake uses
(native/gaussian/airlight.{h,cpp}).

Per frame (or per edit / view change, cached):
- natively, per (light, Gaussian): f1 = exp(-(T(s, b_i) + T(v, b_i)) without Gaussian i's
  own terms) and per light C_sv = exp(-(T(s, v) - beta0 |s - v|)) (`fogshop_factors`);
- per-Gaussian data (centre, scale, amplitude, cull radius, the noise's R_bake / |b - v|,
  albedo: the fog objects' "airlight_color" or 1) and f1 as float textures
  (`gpu_shaders.rbf_data_textures`);
- TILES (default): per view, the Gaussians listed per 8x8 tile of the splat target
  (`_native.rbf_tile_lists`, or `tile_lists` in numpy: the projected cull sphere's screen
  bounds and the bake's per-tile cone test) as two textures; SPLAT: one quad per Gaussian
  (`rbf_splat_batch`).
Per draw:
- the Gaussian sums at 1/scale of the viewport (shaders/rbf_splat_pixel.glsl, the GLSL
  twin of the bake's splat kernels splat_kernels.cpp, incl. its noise): TILES draws one
  full-screen pass whose pixels loop over their tile's list (rbf_tiles_frag.glsl, no
  blending); SPLAT draws each Gaussian's quad over the projected bounds of its cull sphere
  and adds the fragments (ADDITIVE_PREMULT, rbf_splat_frag.glsl). Both give the same two
  RGBA32F targets (bit for bit on llvmpipe, where blending follows primitive order):
  rgb = sum_i albedo_i sum_l I0_l (L_il(Dvp) - L_il(t0)), a = sum_i T_i(t0, Dvp),
  near.r = sum_i T_i(0, t0);
- the fog pass (fog_preview_frag.glsl with PREVIEW_GAUSSIANS) combines them with the
  homogeneous part (beta0 = scene density, scaled by C_sv per light) exactly as the bake's
  eval_rbf does: La = e^{T_near} (La_0 + e^{beta0 t0} sum_i (L_i(Dvp) - L_i(t0))),
  Tr = exp(-(beta0 (Dvp - t0) + sum_i T_i(t0, Dvp))), depth-aware upsampling of the sums
  at HALF / QUARTER.

Limits: f1 and C_sv are set up at the view origin, which for orthographic views is the
view centre rather than each ray's own origin (the bake sets orthographic rays up per
ray), so orthographic previews of Gaussian fog are approximate (the tile lists skip the
cone test there).
"""

import math
import time

import numpy as np

from . import gpu_shaders as gs

# Per-Gaussian cull tolerance on the optical depth of the splat quads and of the
# fragment's cull test. The bake uses GaussianMedium::kDefaultCullEps = 1e-7; the preview
# drops Gaussians that add < 1e-4 to a pixel's optical depth: their radii (and quads)
# shrink by ~25 % (area ~45 %) for a measured difference to the bake in tests/gpu/test_preview_gaussians.py.
CULL_EPS = 1e-4
# The bake's cull tolerance (GaussianMedium::kDefaultCullEps): its cull radii scale the noise.
BAKE_CULL_EPS = 1e-7
# rbf_tiles_frag.glsl reads list positions and Gaussian indices from float textures:
# exact up to 2^24. Beyond that the preview draws the splat instead.
MAX_TILE_ENTRIES = 1 << 24
_SQRT_PI = math.sqrt(math.pi)


def cull_radii(scales, amplitudes, eps=CULL_EPS):
    """R_i = sqrt(ln(c_i sqrt(pi) / (a_i eps))) / a_i, 0 where the log is <= 0 (as
    native/gaussian/medium.h): outside that sphere a segment integrates to < eps."""
    a = np.asarray(scales, np.float64)
    c = np.asarray(amplitudes, np.float64)
    with np.errstate(divide='ignore'):
        arg = np.log(np.where(c > 0.0, c * _SQRT_PI / (a * eps), 1.0))
    return np.where(arg > 0.0, np.sqrt(np.maximum(arg, 0.0)) / a, 0.0)


# The light-side optical depths T(s, b_i) of the last call, kept while the Gaussians,
# beta0 and the lights stay the same: moving the view then recomputes only T(v, b_i)
# and C_sv (one segment per Gaussian instead of 1 + L; natively rbf_preview_factors'
# eye_only=True with _previous_ = the light rows of the last full call).
_light_side = {"key": None, "Ts": None, "medium": None, "previous": None}
# How often the factors were computed with their light rows ("full") and from the cached
# light rows after a view change ("eye_only"): for tests and benchmarks.
factor_stats = {"full": 0, "eye_only": 0}


def clear_cache():
    """Drops the cached light side (on file load / unregister)."""
    _light_side.update(key=None, Ts=None, medium=None, previous=None)


def _factors_from_optical_depth(native, centres, scales, amplitudes, beta0, eye, lights, data_key=None):
    """f1 and C_sv with the RbfMedium binding: culled optical depths of the segments
    s -> b_i and v -> b_i, minus Gaussian i's own part T_i(p, b_i) = c sqrt(pi)/(2a)
    erf(a |b_i - p|) (the line ends at the centre), as FogshopAirlight's constructor
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
    factor_stats["eye_only" if reuse else "full"] += 1
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
    eye row and C_sv are computed (eye_only=True, the light rows of the last full call
    passed as previous=): the same values as a full call at the new eye."""
    a = np.asarray(scales, np.float64)
    c = np.asarray(amplitudes, np.float64)
    eye = np.asarray(eye, np.float64).reshape(3)
    key = None if data_key is None else ("native", data_key, float(beta0), tuple(map(tuple, lights.tolist())))
    if key is not None and _light_side["key"] == key and _light_side["previous"] is not None:
        out = fast(centres, a, c, float(beta0), eye, lights, previous=_light_side["previous"], eye_only=True)
        Ts = _light_side["Ts"]
        factor_stats["eye_only"] += 1
    else:
        out = fast(centres, a, c, float(beta0), eye, lights)
        Ts = np.maximum(np.asarray(out["T_sb"], np.float64) - np.asarray(out["own_sb"], np.float64), 0.0)
        factor_stats["full"] += 1
        if key is not None:
            _light_side.update(key=key, Ts=Ts, medium=None,
                               previous=dict(T_sb=out["T_sb"], own_sb=out["own_sb"]))
    Csv = np.asarray(out["C_sv"], np.float64)
    Tv = np.asarray(out["T_vb"], np.float64) - np.asarray(out["own_vb"], np.float64)
    f1 = np.exp(-(Ts + np.maximum(Tv, 0.0)[None, :]))
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


# Preview scale 'AUTO' (`auto_scale`): the Gaussian sums' texel may be up to sigma_px /
# AUTO_SIGMA_TEXELS wide, sigma_px the projected standard deviation 1 / (a sqrt 2) of the
# smallest visible Gaussian. Measured (benchmarks/gpu_preview, 960x540, 3000 Gaussians of
# the issue-5 scene, smallest sigma_px 15.5): texel = sigma_px / 2 (EIGHTH) differs from the
# bake by 0.65 % of what the Gaussians add, QUARTER by 0.50 %.
AUTO_SIGMA_TEXELS = 2.0
AUTO_SCALES = (8, 4, 2, 1)


def auto_scale(centres, scales, radii, persp, size):
    """The coarsest of AUTO_SCALES whose texel (scale pixels) is at most sigma_px /
    AUTO_SIGMA_TEXELS for every Gaussian visible through the 4x4 _persp_ (projection @
    view) at _size_ (W, H): sigma_px = sigma f / w with sigma = 1 / (a sqrt 2), f the
    pixels per unit of x / w (rows 0 and 1 of _persp_) and w the clip w of the centre
    (1 in orthographic views). Centres at or behind the eye plane do not limit it.
    Nothing visible: the coarsest."""
    P = np.asarray(persp, np.float64).reshape(4, 4)
    _lo, _hi, vis = ndc_bounds(centres, radii, P)
    if not vis.any():
        return AUTO_SCALES[0]
    b = np.asarray(centres, np.float64).reshape(-1, 3)[vis]
    sigma = 1.0 / (np.asarray(scales, np.float64)[vis] * math.sqrt(2.0))
    W, H = size
    f = min(np.linalg.norm(P[0, :3]) * 0.5 * W, np.linalg.norm(P[1, :3]) * 0.5 * H)
    w = b @ P[3, :3] + P[3, 3]
    with np.errstate(divide='ignore'):
        sigma_px = np.where(w > 0.0, sigma * f / w, np.inf)
    smallest = float(sigma_px.min())
    for S in AUTO_SCALES:
        if S * AUTO_SIGMA_TEXELS <= smallest:
            return S
    return AUTO_SCALES[-1]


def _tile_cones(inv_persp, eye, size, scale, tile, tx_n, ty_n):
    """Per tile (perspective views): unit axis (ty, tx, 3) of the cone of its texels'
    view rays and the cosine and sine of the largest angle to its corner rays (a rounding
    margin included), as the bake's GaussianSplat::bin."""
    W, H = size
    S = scale
    off = S // 2 + 0.5

    def directions(x, y):
        ndc = np.stack([x / W * 2.0 - 1.0, y / H * 2.0 - 1.0], -1)
        ones = np.ones(ndc.shape[:-1] + (1,))
        far = np.concatenate([ndc, ones, ones], -1) @ inv_persp.T
        d = far[..., :3] / far[..., 3:] - eye
        return d / np.linalg.norm(d, axis=-1, keepdims=True)
    # Sample positions (full-resolution pixels) of each tile's first and last texel.
    x0 = np.arange(tx_n) * tile * S + off
    x1 = (np.arange(tx_n) * tile + tile - 1) * S + off
    y0 = np.arange(ty_n) * tile * S + off
    y1 = (np.arange(ty_n) * tile + tile - 1) * S + off
    X0, Y0 = np.meshgrid(x0, y0)
    X1, Y1 = np.meshgrid(x1, y1)
    axis = directions(0.5 * (X0 + X1), 0.5 * (Y0 + Y1))
    cos_t = np.ones((ty_n, tx_n))
    for X, Y in ((X0, Y0), (X1, Y0), (X0, Y1), (X1, Y1)):
        cos_t = np.minimum(cos_t, (axis * directions(X, Y)).sum(-1))
    cos_t = np.clip(cos_t - 1e-6, -1.0, 1.0)
    return axis, cos_t, np.sqrt(np.maximum(0.0, 1.0 - cos_t * cos_t))


def tile_lists(centres, radii, persp, size, scale, tile, cone_test=True):
    """Per-tile Gaussian lists of the tile pass (shaders/rbf_tiles_frag.glsl): the splat
    target has ceil(size / scale) texels, texel q standing for the full-resolution pixel
    q scale + scale // 2 (clamped to the image); a tile is _tile_ x _tile_ texels. Each
    Gaussian goes to every tile that its cull sphere's screen bounds (`ndc_bounds`, one
    texel of margin) touch and, in perspective views with _cone_test_, whose cone of view
    rays the sphere meets (the bake's per-tile test: cuts the bounding boxes' corners).
    Returns (first (ty, tx) int64, count (ty, tx) int64, entries (m,) int64 Gaussian
    indices, ascending within a tile)."""
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
    P = np.asarray(persp, np.float64).reshape(4, 4)
    if cone_test and total and np.any(P[3, :3] != 0.0):
        # Sphere (direction u from the eye, angular radius rho) vs the tile's cone
        # (theta): they can meet only if angle(axis, u) <= theta + rho.
        inv = np.linalg.inv(P)
        # The eye: clip x = y = w = 0 there.
        eye = np.linalg.solve(P[[0, 1, 3], :3], -P[[0, 1, 3], 3])
        axis, cos_t, sin_t = _tile_cones(inv, eye, (W, H), S, tile, tx_n, ty_n)
        c = np.asarray(centres, np.float64).reshape(-1, 3)[gid] - eye
        dist = np.linalg.norm(c, axis=1)
        R = np.asarray(radii, np.float64)[gid]
        inside = dist <= R * (1.0 + 1e-9)
        with np.errstate(divide='ignore', invalid='ignore'):
            u = np.where(inside[:, None], 0.0, c / dist[:, None])
            sin_r = np.where(inside, 1.0, R / dist)
        cos_r = np.sqrt(np.maximum(0.0, 1.0 - sin_r * sin_r))
        ct, st = cos_t.ravel()[key], sin_t.ravel()[key]
        sr, cr = sin_r[g], cos_r[g]
        keep = inside[g] | (st * cr + ct * sr < 0.0) | \
            ((axis.reshape(-1, 3)[key] * u[g]).sum(1) >= ct * cr - st * sr)
        key, g = key[keep], g[keep]
    order = np.argsort(key, kind='stable')
    entries = gid[g[order]]
    count = np.bincount(key, minlength=tx_n * ty_n)
    first = np.cumsum(count) - count
    return first.reshape(ty_n, tx_n), count.reshape(ty_n, tx_n), entries


class GaussianFog:
    """GPU side of the Gaussian fog for one set of Gaussians: the data textures, the
    batch, the factors and the tile lists, rebuilt only when an input changes (`update`,
    `update_tiles`). A view change (the user orbiting) recomputes only what depends on
    the eye: f1's eye row (`fogshop_factors` reuses the light rows) and the f1 texture,
    the gauss texture only while the noise (which reads R_bake / |b - eye| there) is on;
    the cull radii and the rest of the gauss texture stay."""

    def __init__(self):
        self.key = None          # (data id, beta0, eye, lights) the factors belong to
        self.data_key = None     # id of the Gaussian arrays the textures hold
        self.gauss_key = None    # (data id, eye of its noise radii) of gauss_tex
        self.bake_radii = None
        self.factor_updates = 0  # factor computations (f1 texture uploads)
        self.gauss_uploads = 0   # gauss texture uploads
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
        self.light_tex = None    # output of the light-fit pass (preview._fit_lights)
        self.light_tex_count = -1
        self.fit_batch = None

    def update(self, native, shader, gaussians, beta0, eye, lights, noise=True):
        """Makes textures/batch/factors current; _gaussians_ = dict(centres, scales,
        amplitudes, key, optionally colors (n, 3) per-Gaussian albedo or None) where
        _key_ changes whenever the arrays do. _noise_: whether the draw uses the noise
        (its per-Gaussian scale R_bake / |b - eye| in the gauss texture then follows the
        eye; without, the gauss texture does not depend on the eye)."""
        n = len(gaussians["scales"])
        lights = [tuple(float(x) for x in s) for s in lights]
        eye = tuple(float(x) for x in eye)
        key = (gaussians["key"], float(beta0), eye, tuple(lights))
        # The gauss texture holds the noise radii of the eye in gauss_key[1]: stale only
        # for other Gaussians, or for another eye while the noise is on.
        gauss_stale = self.gauss_key is None or self.gauss_key[0] != gaussians["key"] or \
            (noise and self.gauss_key[1] != eye)
        if key != self.key or gauss_stale:
            t0 = time.perf_counter()
            if gaussians["key"] != self.data_key:
                # View-independent: positions and the cull radii (preview's and bake's).
                self.centres = np.asarray(gaussians["centres"], np.float64).reshape(-1, 3)
                self.radii = cull_radii(gaussians["scales"], gaussians["amplitudes"])
                self.bake_radii = cull_radii(gaussians["scales"], gaussians["amplitudes"], BAKE_CULL_EPS)
                self.data_key = gaussians["key"]
                self.tiles_key = None
                self.count = n
            if gauss_stale:
                # The noise's per-Gaussian scale R_bake / |b - eye| (splat.h), as the bake.
                dist = np.linalg.norm(self.centres - np.asarray(eye, np.float64), axis=1)
                with np.errstate(divide='ignore', invalid='ignore'):
                    noise_radii = np.where(dist > 0.0, self.bake_radii / dist, 0.0)
                self.gauss_tex = gs.rbf_gauss_texture(
                    self.centres, gaussians["scales"], gaussians["amplitudes"], self.radii,
                    albedo=gaussians.get("colors"), noise_radii=noise_radii)
                self.gauss_key = (gaussians["key"], eye)
                self.gauss_uploads += 1
            if key != self.key:
                f1, self.Csv = fogshop_factors(native, gaussians["centres"], gaussians["scales"],
                                               gaussians["amplitudes"], beta0, eye, lights,
                                               data_key=gaussians["key"])
                self.f1_tex = gs.rbf_f1_texture(f1, n)
                self.key = key
                self.factor_updates += 1
            self.factor_ms = (time.perf_counter() - t0) * 1e3
        if shader is not None and self.batch_count != n:
            self.batch = gs.rbf_splat_batch(shader, n)
            self.batch_count = n

    def update_tiles(self, native, persp, size, scale):
        """Makes the tile lists current for the view _persp_ (4x4) at _size_ and _scale_
        (`_native.rbf_tile_lists` when the module has it, else `tile_lists`: the same).
        False (and no textures) when the lists exceed MAX_TILE_ENTRIES: the caller draws
        the splat instead."""
        P = np.asarray(persp, np.float64).reshape(4, 4)
        # The lists depend on the Gaussians (centres, radii) and the view, not on f1.
        key = (self.data_key, tuple(P.ravel().tolist()), tuple(size), int(scale))
        if key != self.tiles_key:
            t0 = time.perf_counter()
            fast = getattr(native, "rbf_tile_lists", None)
            if fast is not None:
                first, count, entries = fast(self.centres, self.radii, P, int(size[0]), int(size[1]),
                                             int(scale), gs.RBF_TILE)
            else:
                first, count, entries = tile_lists(self.centres, self.radii, P, size, scale, gs.RBF_TILE)
            self.tile_pairs = len(entries)
            self.tile_tex = gs.rbf_tile_textures(first, count, entries) \
                if len(entries) <= MAX_TILE_ENTRIES else None
            self.tiles_key = key
            self.tiles_ms = (time.perf_counter() - t0) * 1e3
        return self.tile_tex is not None
