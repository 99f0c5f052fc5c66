"""Model 'hoffman02' (Hoffman & Preetham 2002, hoffman02_model.cpp): sun lamps in a Rayleigh +
Mie medium with per-channel extinction, per pixel against an independent scipy quadrature
written out here (Rayleigh beta ~ (550 / lambda)^4 with lambda = 650 / 570 / 475 nm, HG Mie,
fog below a layer top or HP's unattenuated sun), its per-channel transmittance, the limit
without Rayleigh (= the sun model of every other model), and its refusals."""
import math

import numpy as np
import pytest
from scipy import integrate

import _native
from reference_util import hg, layer_top_crossing, phase_value, sun_layer_paths
from scene_util import camera_matrix, in_camera_space, perspective, pixel_dirs_camera, plane_z, rotation_x

W, H = 16, 12
FOV = math.radians(70.0)
BETA_M = 0.03          # Mie (sigma_t)
BETA_R550 = 0.02       # Rayleigh at 550 nm (exaggerated so the colour shift is visible)
ALBEDO = (0.9, 0.9, 0.9)
LAMBDA = (650.0, 570.0, 475.0)
SUN_DIR = np.array([[0.4, 0.3, -0.6], [-0.7, 0.1, -0.3]])
SUN_E = np.array([[3.0, 2.5, 2.0], [1.0, 1.5, 2.0]])
PLANE_Z = -12.0
CAM = camera_matrix(rotation_x(math.radians(10.0)), [0.0, 0.0, 2.0])


def beta_r():
    return np.array([BETA_R550 * (550.0 / lam) ** 4 for lam in LAMBDA])


def reference(o, d, t0, t1, fog_top, g):
    bR = beta_r()
    total = np.zeros(3)
    end = t1 if math.isfinite(t1) else 2e3
    for w, E in zip(SUN_DIR, SUN_E):
        w = w / np.linalg.norm(w)
        mu = -float(w @ d)
        mu_s = -w[2]
        for c in range(3):
            sigma = bR[c] + BETA_M

            def f(t):
                paths = sun_layer_paths(o, d, t0, t, fog_top, mu_s)
                return 0.0 if paths is None else math.exp(-sigma * sum(paths))

            pts = layer_top_crossing(o, d, t0, end, fog_top)
            val, _ = integrate.quad(f, t0, end, points=pts or None, limit=400, epsabs=0, epsrel=1e-10)
            total[c] += ALBEDO[c] * E[c] * (bR[c] * phase_value("rayleigh", mu) + BETA_M * hg(mu, g)) * val
    return total


def bake(fog_top, g=0.0, rayleigh_density=BETA_R550, model="hoffman02", **kw):
    v, tris = in_camera_space(CAM, plane_z(PLANE_Z, x=(-50.0, 50.0), y=(-50.0, 0.0)))
    args = dict(width=W, height=H, cam_to_world=CAM, projection=perspective(FOV, W, H), vertices=v,
                triangles=tris, light_positions=np.zeros((0, 3)), light_intensities=np.zeros((0, 3)),
                sigma_t=BETA_M, albedo=ALBEDO, phase="hg" if g else "isotropic", g=g, model=model,
                aa_samples=1, sun_directions=SUN_DIR, sun_irradiances=SUN_E, fog_top=fog_top,
                rayleigh_density=rayleigh_density)
    args.update(kw)
    return _native.bake(**args)


@pytest.mark.parametrize("fog_top,g", [(math.inf, 0.0), (6.0, 0.0), (6.0, 0.7)])
def test_airlight_and_transmittance_per_channel(fog_top, g):
    out = bake(fog_top, g)
    dirs = pixel_dirs_camera(FOV, W, H) @ CAM[:3, :3].T
    o = CAM[:3, 3]
    worst = 0.0
    sigma = beta_r() + BETA_M
    for j in range(H):
        for i in range(W):
            d = dirs[j, i]
            D = float(out["depth"][j, i])
            want = reference(o, d, 0.0, D, fog_top, g)
            got = out["airlight"][j, i]
            assert np.all(np.isfinite(got))
            worst = max(worst, float(np.max(np.abs(got - want) / want)))
            T = np.exp(-sigma * D) if math.isfinite(D) else np.zeros(3)
            np.testing.assert_allclose(out["transmittance"][j, i], T, rtol=1e-5, atol=1e-12)
    assert worst < 2e-5, worst
    # The blue channel is extinguished most (Rayleigh ~ 1/lambda^4).
    hit = np.isfinite(out["depth"])
    assert np.all(out["transmittance"][hit][:, 2] < out["transmittance"][hit][:, 0])


def test_without_rayleigh_equals_the_sun_model():
    hp = bake(6.0, 0.5, rayleigh_density=0.0)
    other = bake(6.0, 0.5, rayleigh_density=0.0, model="biri06")
    np.testing.assert_allclose(hp["airlight"], other["airlight"], rtol=1e-5, atol=1e-12)
    np.testing.assert_allclose(hp["transmittance"], other["transmittance"], rtol=1e-6, atol=1e-12)


def test_refusals():
    with pytest.raises(ValueError, match="sun lamps only"):
        bake(6.0, light_positions=np.array([[0.0, 5.0, 2.0]]), light_intensities=np.array([[1.0, 1.0, 1.0]]))
    with pytest.raises(ValueError, match="Henyey-Greenstein"):
        bake(6.0, phase="rayleigh")
    with pytest.raises(ValueError, match="rayleigh_density"):
        bake(6.0, rayleigh_density=-1.0)
    with pytest.raises(ValueError, match="rayleigh_density"):
        bake(6.0, rayleigh_density=float("nan"))
    with pytest.raises(ValueError, match="surface"):
        bake(6.0, surface=True)
