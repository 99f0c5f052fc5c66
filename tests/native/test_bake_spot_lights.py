"""Bakes with Blender spot lights: per pixel against an independent scipy quadrature of the
single-scattering integral with Cycles' spot profile written out here (NOTES.md:
I0 cos(theta) smoothstep(0, (1 - cos(size/2)) blend, cos(theta) - cos(size/2))), the cone
edges bracketed by sampling; the near plane; the phase; the argument checks; and that the
point-light path is unchanged (bit-identical) without spot lights."""
import math

import numpy as np
import pytest
from scipy import integrate, optimize

import _native
from reference_util import hg
from scene_util import camera_matrix, perspective, pixel_dirs_camera, plane_z, rotation_x

W, H = 24, 16
FOV = math.radians(60.0)
SIGMA_T = 0.15
TILT = math.radians(-10.0)
CAM_POS = np.array([0.0, 0.5, 1.0])
PLANE_Z = -9.0
SPOT_POS = np.array([[0.5, 3.0, -5.0], [-2.0, 1.0, -3.0]])
SPOT_AXIS = np.array([[0.1, -1.0, -0.2], [0.6, -0.3, -1.0]])
SPOT_I = np.array([[30.0, 20.0, 10.0], [5.0, 8.0, 12.0]])
SPOT_SIZE = np.array([math.radians(50.0), math.radians(35.0)])
ALBEDO = (0.9, 0.8, 0.6)
POINT_POS = np.array([[1.0, 0.0, -4.0]])
POINT_I = np.array([[2.0, 2.0, 3.0]])


def profile(axis, size, blend, u):
    """Cycles' spot factor for the unit direction u (light -> point)."""
    c = float(axis @ u)
    ch = math.cos(size / 2)
    if c <= ch:
        return 0.0
    e1 = (1 - ch) * blend
    if e1 <= 0:
        return c
    t = min(max((c - ch) / e1, 0.0), 1.0)
    return c * t * t * (3 - 2 * t)


def reference(o, d, t0, t1, blend, g=0.0):
    """sigma_s sum_spots int_t0^t1 I(theta) p e^{-sigma_t (|x - s| + t - t0)} / |x - s|^2 dt."""
    total = np.zeros(3)
    end = t1 if math.isfinite(t1) else t0 + 400.0   # e^{-0.15 * 400}: negligible beyond
    for s, axis, I0, size in zip(SPOT_POS, SPOT_AXIS, SPOT_I, SPOT_SIZE):
        axis = axis / np.linalg.norm(axis)
        ch = math.cos(size / 2)

        def edge(t, c_edge):
            w = o + t * d - s
            return float(axis @ w) / math.sqrt(w @ w) - c_edge

        def f(t):
            w = o + t * d - s
            r = math.sqrt(w @ w)
            return profile(axis, size, blend, w / r) * hg(-(w @ d) / r, g) * \
                math.exp(-SIGMA_T * (r + t - t0)) / (r * r)
        # Breakpoints: cone (and blend-cone) crossings bracketed on a fine grid, the peak.
        ts = t0 + (end - t0) * np.linspace(0.0, 1.0, 1201) ** 2
        pts = {t0, end}
        for c_edge in (ch, ch + (1 - ch) * blend):
            v = [edge(t, c_edge) for t in ts]
            for i in range(len(ts) - 1):
                if v[i] * v[i + 1] < 0:
                    pts.add(optimize.brentq(edge, ts[i], ts[i + 1], args=(c_edge,), xtol=1e-13))
        a = float((s - o) @ d)
        if t0 < a < end:
            pts.add(a)
        pts = sorted(pts)
        val = sum(integrate.quad(f, lo, hi, epsabs=0, epsrel=1e-9, limit=400)[0]
                  for lo, hi in zip(pts, pts[1:]) if hi > lo)
        total += SIGMA_T * np.array(ALBEDO) * I0 * val
    return total


def scene(**kw):
    vertices, triangles = plane_z(PLANE_Z)
    args = dict(width=W, height=H, cam_to_world=camera_matrix(rotation_x(TILT), CAM_POS),
                projection=perspective(FOV, W, H), vertices=vertices, triangles=triangles,
                light_positions=np.zeros((0, 3)), light_intensities=np.zeros((0, 3)), sigma_t=SIGMA_T,
                albedo=ALBEDO, threads=2, aa_samples=1)
    args.update(kw)
    return args


def spots(blend):
    return dict(spot_positions=SPOT_POS, spot_axes=SPOT_AXIS, spot_intensities=SPOT_I, spot_size=SPOT_SIZE,
                spot_blend=np.full(2, blend))


def pixel_rays():
    dirs = pixel_dirs_camera(FOV, W, H) @ rotation_x(TILT).T
    return dirs


def check(out, blend, near=0.0, g=0.0, rtol=1e-5):
    dirs = pixel_rays()
    view = rotation_x(TILT) @ np.array([0.0, 0.0, -1.0])
    A = out["airlight"]
    errs, checked = [], 0
    for j in range(0, H, 3):
        for i in range(0, W, 2):
            d = dirs[j, i]
            t1 = (PLANE_Z - CAM_POS[2]) / d[2] if d[2] < 0 else math.inf
            t0 = near / float(d @ view)
            ref = reference(CAM_POS, d, t0, t1, blend, g)
            scale = max(ref.max(), 1e-6)
            errs.append(np.abs(A[j, i] - ref).max() / scale)
            checked += ref.max() > 1e-4
    assert checked > 20, "the frame should see the spots' cones"
    print(f"checked {checked}, max relative error {max(errs):.2e}")
    assert max(errs) < rtol, f"max relative error {max(errs):.2e}"


@pytest.mark.parametrize("blend", [0.0, 0.3])
def test_spot_bake_matches_reference(blend):
    check(_native.bake(**scene(**spots(blend))), blend)


def test_spot_bake_near_plane():
    near = 1.5
    check(_native.bake(**scene(clip_start=near, **spots(0.2))), 0.2, near=near)


@pytest.mark.parametrize("model", ["biri06", "quadrature"])
def test_spot_bake_hg_phase(model):
    check(_native.bake(**scene(phase="hg", g=0.5, model=model, **spots(0.1))), 0.1, g=0.5)


def test_spot_adds_to_point_lights():
    """Point + spot = point + spot baked apart (the spot term is additive)."""
    both = _native.bake(**scene(light_positions=POINT_POS, light_intensities=POINT_I, **spots(0.2)))
    point = _native.bake(**scene(light_positions=POINT_POS, light_intensities=POINT_I))
    spot = _native.bake(**scene(**spots(0.2)))
    np.testing.assert_allclose(both["airlight"], point["airlight"] + spot["airlight"], rtol=1e-5, atol=1e-7)
    np.testing.assert_array_equal(both["transmittance"], point["transmittance"])


@pytest.mark.parametrize("model", ["sun05", "sun05_exact", "quadrature"])
def test_no_spots_is_bit_identical(model):
    """The point-light paths are untouched: no spot arguments and zero spots give the same bits."""
    kw = dict(light_positions=POINT_POS, light_intensities=POINT_I, model=model, aa_samples=4, clip_start=0.3)
    a = _native.bake(**scene(**kw))
    b = _native.bake(**scene(spot_positions=np.zeros((0, 3)), spot_axes=np.zeros((0, 3)),
                             spot_intensities=np.zeros((0, 3)), spot_size=np.zeros(0), spot_blend=np.zeros(0), **kw))
    for key in ("airlight", "transmittance", "depth"):
        np.testing.assert_array_equal(a[key], b[key])


def test_spot_argument_errors():
    with pytest.raises(ValueError, match="together"):
        _native.bake(**scene(spot_positions=SPOT_POS))
    bad = spots(0.1)
    bad["spot_size"] = np.array([0.5])
    with pytest.raises(ValueError, match="spot_size"):
        _native.bake(**scene(**bad))
    bad = spots(0.1)
    bad["spot_blend"] = np.array([0.1, 1.5])
    with pytest.raises(ValueError, match="spot_blend"):
        _native.bake(**scene(**bad))
    bad = spots(0.1)
    bad["spot_axes"] = np.zeros((2, 3))
    with pytest.raises(ValueError, match="axis"):
        _native.bake(**scene(**bad))
    bad = spots(0.1)
    bad["spot_positions"] = np.array([[np.nan, 0, 0], [0, 0, 0]])
    with pytest.raises(ValueError, match="position"):
        _native.bake(**scene(**bad))
    # (spots with Gaussians are baked now: test_bake_gaussians_lights.py)
