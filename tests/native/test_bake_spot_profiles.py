"""A light distribution over the whole sphere (spot_profiles: a point light's IES profile,
fitted as I(c) = I0 sum_k p_k c^k about an axis) against an independent scipy quadrature of
the single-scattering integral with that profile written out here, for the closed form
(Pegoraro 2010: sun05, pegoraro10), Biri's model and the quadrature reference; the per-row
choice of cone or profile; the argument checks."""
import math

import numpy as np
import pytest
from scipy import integrate

import _native
from reference_util import hg
from scene_util import perspective, pixel_dirs_camera, plane_z

W, H, FOV, SIGMA = 10, 8, 1.1, 0.2
LIGHT = np.array([0.4, 0.8, -4.0])
AXIS = np.array([0.2, -1.0, -0.3]) / np.linalg.norm([0.2, -1.0, -0.3])
PROFILE = [0.2, 0.5, 0.9]   # 0.2 + 0.5 c + 0.9 c^2 > 0 on [-1, 1]
PLANE_Z = -7.0


def spots(profile=PROFILE, size=math.pi, blend=0.0):
    return dict(spot_positions=[LIGHT], spot_axes=[AXIS], spot_intensities=[[1.0, 1.0, 1.0]], spot_size=[size],
                spot_blend=[blend], spot_profiles=[profile])


def bake(**kw):
    v, t = plane_z(PLANE_Z, x=(-80.0, 80.0), y=(-80.0, 80.0))
    a = dict(width=W, height=H, cam_to_world=np.eye(4), projection=perspective(FOV, W, H), vertices=v,
             triangles=t, light_positions=np.zeros((0, 3)), light_intensities=np.zeros((0, 3)), sigma_t=SIGMA,
             aa_samples=1, threads=2)
    a.update(kw)
    return _native.bake(**a)["airlight"][..., 0].astype(np.float64)


def reference(g=0.0, profile=PROFILE):
    d = pixel_dirs_camera(FOV, W, H)
    out = np.empty((H, W))
    for j in range(H):
        for i in range(W):
            u = d[j, i]
            t1 = PLANE_Z / u[2]

            def f(t):
                w = t * u - LIGHT
                r = math.sqrt(w @ w)
                c = float(AXIS @ w) / r
                I = max(0.0, sum(p * c ** k for k, p in enumerate(profile)))
                return I * hg(-(w @ u) / r, g) * math.exp(-SIGMA * (r + t)) / (r * r)

            tc = float(LIGHT @ u)
            pts = [tc] if 0.0 < tc < t1 else None
            out[j, i] = SIGMA * integrate.quad(f, 0.0, t1, points=pts, epsabs=0.0, epsrel=1e-10, limit=400)[0]
    return out


@pytest.fixture(scope="module")
def ref_iso():
    return reference()


@pytest.mark.parametrize("model, rtol", [("sun05", 1e-6), ("sun05_exact", 1e-6), ("pegoraro10", 1e-6),
                                         ("biri06", 1e-6), ("quadrature", 1e-6)])
def test01_profile_matches_quadrature(model, rtol, ref_iso):
    np.testing.assert_allclose(bake(model=model, **spots()), ref_iso, rtol=rtol)


@pytest.mark.parametrize("model", ["pegoraro10", "quadrature", "biri06"])
def test02_anisotropic_phase(model):
    np.testing.assert_allclose(bake(model=model, phase="hg", g=0.5, **spots()), reference(g=0.5), rtol=1e-5)


def test03_constant_profile_is_a_point_light():
    point = bake(light_positions=[LIGHT], light_intensities=[[1.0] * 3], model="sun05_exact")
    np.testing.assert_allclose(bake(model="sun05_exact", **spots(profile=[1.0])), point, rtol=1e-6)


def test04_zero_row_keeps_the_cone_and_rows_are_per_spot():
    two = dict(spot_positions=[LIGHT, LIGHT + 1.0], spot_axes=[AXIS, AXIS], spot_intensities=[[1.0] * 3] * 2,
               spot_size=[math.pi, 0.8], spot_blend=[0.0, 0.2], spot_profiles=[PROFILE, [0.0, 0.0, 0.0]])
    cone_only = dict(spot_positions=[LIGHT + 1.0], spot_axes=[AXIS], spot_intensities=[[1.0] * 3], spot_size=[0.8],
                     spot_blend=[0.2])
    got = bake(model="sun05_exact", **two)
    np.testing.assert_allclose(got, bake(model="sun05_exact", **spots()) + bake(model="sun05_exact", **cone_only),
                               rtol=1e-6)


def test05_shadows_and_surfaces_take_the_profile(ref_iso):
    v, t = plane_z(PLANE_Z, x=(-80.0, 80.0), y=(-80.0, 80.0))
    lit = bake(model="sun05_exact", shadows=True, **spots())   # the floor casts no shadow on the fog above it
    np.testing.assert_allclose(lit, ref_iso, rtol=1e-5)
    out = _native.bake(width=W, height=H, cam_to_world=np.eye(4), projection=perspective(FOV, W, H), vertices=v,
                       triangles=t, light_positions=np.zeros((0, 3)), light_intensities=np.zeros((0, 3)),
                       sigma_t=SIGMA, aa_samples=1, surface=True, **spots())
    assert all(np.all(np.isfinite(a)) for a in out.values() if isinstance(a, np.ndarray))


@pytest.mark.parametrize("kw, match", [
    (dict(spot_profiles=[[0.1, float("nan")]]), "profile coefficients must be finite"),
    (dict(spot_size=[1.0]), "a profile .* needs spot_size pi, spot_blend 0"),
    (dict(spot_profiles=[[1.0], [1.0]]), r"spot_profiles: expected shape \(1, K \+ 1\)"),
])
def test06_bad_profiles_are_refused(kw, match):
    args = spots()
    args.update(kw)
    with pytest.raises(ValueError, match=match):
        bake(**args)


def test07_profiles_need_spots_and_homogeneous_fog():
    with pytest.raises(ValueError, match="spot_profiles needs the spot lights"):
        bake(spot_profiles=[[1.0]])
    with pytest.raises(ValueError, match="IES profile .* not in Gaussian fog"):
        bake(rbf_centres=[[0.0, 0.0, -5.0]], rbf_scales=[1.0], rbf_amplitudes=[0.5], **spots())
