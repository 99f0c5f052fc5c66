"""Bakes of anisotropic media: the biri06 and quadrature models per pixel against an
independent scipy quadrature of the single-scattering integral with the phase function
written out here (Cycles' HG sign: g > 0 forward), and the models' phase support."""
import math

import numpy as np
import pytest
from scipy import integrate

import _native
from reference_util import phase_value
from scene_util import camera_matrix, perspective, pixel_dirs_camera, plane_z, rotation_x

W, H = 40, 28
FOV = math.radians(60.0)
SIGMA_T = 0.12
TILT = math.radians(-8.0)
CAM_POS = np.array([0.0, 0.5, 1.0])
PLANE_Z = -9.0
LIGHTS = np.array([[0.8, 0.2, -4.0], [-3.0, 2.0, -6.0]])   # the first one is in the frame
INTENSITY = np.array([[3.0, 2.0, 1.0], [1.0, 1.0, 2.0]])
ALBEDO = (0.9, 0.8, 0.6)


def reference(o, d, t1, name, g):
    """sigma_s int_0^t1 p(cos theta) I0 e^{-sigma_t (|x - s| + t)} / |x - s|^2 dt, per light."""
    total = np.zeros(3)
    for s, I0 in zip(LIGHTS, INTENSITY):
        def f(t):
            x = o + t * d
            w = x - s
            r = math.sqrt(w @ w)
            mu = -(w @ d) / r         # light's travel direction (s -> x) . scattered one (x -> eye, -d)
            return phase_value(name, mu, g) * math.exp(-SIGMA_T * (r + t)) / (r * r)
        a = max(0.0, (s - o) @ d)     # closest approach: split there (the peak)
        pts = [0.0, min(a, t1), t1]
        val = sum(integrate.quad(f, lo, hi, epsabs=0, epsrel=1e-10, limit=400)[0]
                  for lo, hi in zip(pts, pts[1:]) if hi > lo)
        total += SIGMA_T * np.array(ALBEDO) * I0 * val
    return total


def bake(**kw):
    vertices, triangles = plane_z(PLANE_Z)
    args = dict(width=W, height=H, cam_to_world=camera_matrix(rotation_x(TILT), CAM_POS),
                projection=perspective(FOV, W, H), vertices=vertices, triangles=triangles,
                light_positions=LIGHTS, light_intensities=INTENSITY, sigma_t=SIGMA_T, albedo=ALBEDO,
                threads=2, aa_samples=1)
    args.update(kw)
    return _native.bake(**args)


@pytest.mark.parametrize("name,g,bound", [("hg", 0.6, 1e-3), ("hg", -0.4, 1e-3), ("rayleigh", 0.0, 1e-3),
                                          ("mie_hazy", 0.0, 1e-3), ("mie_murky", 0.0, 1e-3)])
@pytest.mark.parametrize("clip_start", [0.0, 3.0])
def test01_biri06_bake_matches_quadrature(name, g, bound, clip_start):
    out = bake(model="biri06", phase=name, g=g, clip_start=clip_start)
    dirs = pixel_dirs_camera(FOV, W, H) @ rotation_x(TILT).T
    errs = []
    for j in range(1, H, 5):
        for i in range(1, W, 5):
            d = dirs[j, i]
            cos_view = -(d @ (rotation_x(TILT) @ np.array([0, 0, 1.0])))
            t0 = clip_start / cos_view
            t1 = (CAM_POS[2] - PLANE_Z) / -d[2] - t0
            ref = reference(CAM_POS + t0 * d, d, t1, name, g)
            errs.append(np.max(np.abs(out["airlight"][j, i] / ref - 1)))
    errs = np.array(errs)
    print(f"biri06 bake {name} g={g} clip_start={clip_start}: mean rel {errs.mean():.2g} max {errs.max():.2g}")
    assert errs.max() < bound


def test02_quadrature_model_is_phase_aware():
    hg = bake(model="quadrature", phase="hg", g=0.6)
    biri = bake(model="biri06", phase="hg", g=0.6)
    np.testing.assert_allclose(hg["airlight"], biri["airlight"], rtol=2e-3)
    iso = bake(model="quadrature")
    # Forward scattering: the pixel looking nearest the in-frame light gets brighter than
    # with the isotropic phase, the pixels looking away darker.
    ratio = hg["airlight"][..., 0] / iso["airlight"][..., 0]
    assert ratio.max() > 1.5 and ratio.min() < 0.8


def test03_sun05_refuses_anisotropic_phase():
    for model in ("sun05", "sun05_exact"):
        with pytest.raises(ValueError, match="biri06"):
            bake(model=model, phase="hg", g=0.6)
        with pytest.raises(ValueError, match="isotropic"):
            bake(model=model, phase="rayleigh")
    # HG with g = 0 is the isotropic phase: accepted, same image.
    np.testing.assert_array_equal(bake(phase="hg", g=0.0)["airlight"], bake()["airlight"])


def test04_phase_argument_errors():
    with pytest.raises(ValueError, match="mie_hazy"):
        bake(model="biri06", phase="mie")
    with pytest.raises(ValueError, match="g"):
        bake(model="biri06", phase="hg", g=1.0)
    with pytest.raises(ValueError, match="g"):
        bake(model="biri06", phase="hg", g=float("nan"))
    with pytest.raises(ValueError, match="only the 'hg'"):
        bake(model="biri06", phase="rayleigh", g=0.5)


def test05_biri06_is_registered():
    names = [name for name, _ in _native.models()]
    assert "biri06" in names
