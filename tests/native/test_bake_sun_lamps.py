"""Bakes with sun lamps (sunlight_layer.h) per pixel against an independent scipy quadrature of
the single-scattering integral written out here (fog below a layer top, or Hoffman &
Preetham's unattenuated sun without one: reference_util.sun_layer_paths), any phase, the near plane, camera above the
layer; the 'baseline' model against its definition; the argument checks."""
import math

import numpy as np
import pytest
from scipy import integrate

import _native
from reference_util import hg, layer_top_crossing, sun_layer_paths
from scene_util import (camera_matrix, in_camera_space, orthographic, perspective, pixel_dirs_camera, plane_z,
                        rotation_x)

W, H = 20, 14
FOV = math.radians(70.0)
SIGMA_T = 0.08
ALBEDO = (0.9, 0.8, 0.6)
SUN_DIR = np.array([[0.4, 0.3, -0.6], [-0.7, 0.1, -0.15]])   # the second one low (grazing)
SUN_E = np.array([[3.0, 2.5, 2.0], [1.0, 1.5, 2.0]])
PLANE_Z = -12.0   # a wall (in camera space) in the lower half of the frame


def reference(o, d, t0, t1, fog_top, g):
    """sum_suns sigma_s E p(theta) int_t0^t1 e^{-tau_view(t) - tau_sun(t)} dt with the
    optical depths from the geometry: fog only below fog_top (world z)."""
    total = np.zeros(3)
    end = t1 if math.isfinite(t1) else 1e3   # e^{-0.08 * 1000}: negligible beyond
    for w, E in zip(SUN_DIR, SUN_E):
        w = w / np.linalg.norm(w)
        p = hg(-float(w @ d), g)
        mu_s = -w[2]

        def f(t):
            paths = sun_layer_paths(o, d, t0, t, fog_top, mu_s)
            return 0.0 if paths is None else math.exp(-SIGMA_T * sum(paths))

        pts = layer_top_crossing(o, d, t0, end, fog_top)
        val, _ = integrate.quad(f, t0, end, points=pts or None, limit=400, epsabs=0, epsrel=1e-10)
        total += SIGMA_T * np.asarray(ALBEDO) * E * p * val
    return total


def bake(cam, fog_top, g=0.0, model=None, near=0.0, **kw):
    phase = "hg" if g != 0.0 else "isotropic"
    if model is None:
        model = "biri06" if g != 0.0 else "sun05"
    v, tris = in_camera_space(cam, plane_z(PLANE_Z, x=(-50.0, 50.0), y=(-50.0, 0.0)))
    return _native.bake(width=W, height=H, cam_to_world=cam, projection=perspective(FOV, W, H),
                        vertices=v, triangles=tris, light_positions=np.zeros((0, 3)),
                        light_intensities=np.zeros((0, 3)), sigma_t=SIGMA_T, albedo=ALBEDO, phase=phase,
                        g=g, model=model, aa_samples=1, clip_start=near,
                        sun_directions=SUN_DIR, sun_irradiances=SUN_E, fog_top=fog_top, **kw)


def check(cam, fog_top, g=0.0, model=None, near=0.0, rtol=2e-5):
    out = bake(cam, fog_top, g, model, near)
    dirs = pixel_dirs_camera(FOV, W, H) @ cam[:3, :3].T
    o = cam[:3, 3]
    forward = -cam[:3, 2]
    worst = 0.0
    for j in range(H):
        for i in range(W):
            d = dirs[j, i]
            t0 = near / float(d @ forward)
            want = reference(o, d, t0, float(out["depth"][j, i]), fog_top, g)
            got = out["airlight"][j, i]
            assert np.all(np.isfinite(got))
            worst = max(worst, float(np.max(np.abs(got - want) / np.maximum(want, 1e-30))))
    assert worst < rtol, worst
    return out


CAM_LEVEL = camera_matrix(rotation_x(math.radians(10.0)), [0.0, 0.0, 2.0])


@pytest.mark.parametrize("fog_top", [math.inf, 6.0])
def test_sun_isotropic(fog_top):
    check(CAM_LEVEL, fog_top)


def test_sun_anisotropic_and_near_plane():
    check(CAM_LEVEL, 6.0, g=0.6, near=0.7)


def test_sun_quadrature_model():
    check(CAM_LEVEL, 6.0, g=-0.3, model="quadrature")


def test_camera_above_the_layer():
    # 8 m above a top at z = 3, looking 30 deg down: the lower rays enter the fog.
    cam = camera_matrix(rotation_x(math.radians(60.0)), [0.0, 0.0, 11.0])
    out = check(cam, 3.0)
    assert out["airlight"].max() > 0.0


def test_baseline_is_the_least_squares_constant_colour():
    ref = bake(CAM_LEVEL, 6.0)
    base = bake(CAM_LEVEL, 6.0, model="baseline")
    f = 1.0 - ref["transmittance"].astype(float)
    for c in range(3):
        C = float(np.sum(ref["airlight"][..., c] * f[..., c]) / np.sum(f[..., c] ** 2))
        np.testing.assert_allclose(base["airlight"][..., c], C * f[..., c], rtol=1e-5, atol=1e-9)
    np.testing.assert_array_equal(base["transmittance"], ref["transmittance"])
    # The baseline cannot follow the sun's view dependence: it differs from the physics.
    assert np.max(np.abs(base["airlight"] - ref["airlight"]) / ref["airlight"]) > 0.05


def test_no_suns_is_unchanged():
    cam = CAM_LEVEL
    args = dict(width=W, height=H, cam_to_world=cam, projection=perspective(FOV, W, H),
                vertices=np.zeros((0, 3), np.float32), triangles=np.zeros((0, 3), np.uint32),
                light_positions=np.array([[1.0, 2.0, -3.0]]), light_intensities=np.array([[1.0, 1.0, 1.0]]),
                sigma_t=SIGMA_T)
    a = _native.bake(**args)
    b = _native.bake(**args, sun_directions=np.zeros((0, 3)), sun_irradiances=np.zeros((0, 3)), fog_top=4.0)
    np.testing.assert_array_equal(a["airlight"], b["airlight"])


def test_bad_sun_input():
    base = dict(width=4, height=4, cam_to_world=np.eye(4), projection=perspective(FOV, 4, 4),
                vertices=np.zeros((0, 3), np.float32), triangles=np.zeros((0, 3), np.uint32),
                light_positions=np.zeros((0, 3)), light_intensities=np.zeros((0, 3)), sigma_t=0.1)
    with pytest.raises(ValueError, match="together"):
        _native.bake(**base, sun_directions=SUN_DIR)
    with pytest.raises(ValueError, match="direction"):
        _native.bake(**base, sun_directions=np.zeros((1, 3)), sun_irradiances=np.ones((1, 3)))
    with pytest.raises(ValueError, match="irradiance"):
        _native.bake(**base, sun_directions=SUN_DIR[:1], sun_irradiances=-np.ones((1, 3)))
    with pytest.raises(ValueError, match="fog_top"):
        _native.bake(**base, sun_directions=SUN_DIR[:1], sun_irradiances=np.ones((1, 3)), fog_top=math.nan)
    # (suns with Gaussians are baked now: test_bake_gaussians_lights.py)


def test_orthographic_camera():
    """Orthographic rays have their own origins (the bake's per-ray path, not the SoA one)."""
    cam = camera_matrix(rotation_x(math.radians(80.0)), [0.0, 0.0, 2.0])  # looks along +y, 10 deg down
    scale = 6.0
    out = _native.bake(width=W, height=H, cam_to_world=cam, projection=orthographic(scale, W, H),
                       vertices=np.zeros((0, 3), np.float32), triangles=np.zeros((0, 3), np.uint32),
                       light_positions=np.zeros((0, 3)), light_intensities=np.zeros((0, 3)), sigma_t=SIGMA_T,
                       albedo=ALBEDO, phase="hg", g=0.3, model="biri06", aa_samples=1,
                       sun_directions=SUN_DIR, sun_irradiances=SUN_E, fog_top=4.0)
    r, t = scale / 2, scale / 2 * H / W
    d = -cam[:3, 2]
    worst = 0.0
    for j in range(H):
        for i in range(W):
            x = (2 * (i + 0.5) / W - 1) * r
            y = (1 - 2 * (j + 0.5) / H) * t
            o = cam[:3, 3] + x * cam[:3, 0] + y * cam[:3, 1] + 0.1 * d   # rays start on the near plane
            want = reference(o, d, 0.0, math.inf, 4.0, 0.3)
            got = out["airlight"][j, i]
            worst = max(worst, float(np.max(np.abs(got - want) / want)))
    assert worst < 2e-5, worst
