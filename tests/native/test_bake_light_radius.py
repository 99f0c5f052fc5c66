"""A point or spot light's Radius (light_radii, spot_radii) against an independent reference.

Cycles 3.4 samples a light of radius r as a disk facing each shading point, of uniform
radiance with a cosine lobe (docs/models.md, "Light size"). The reference integrates that
disk here with scipy, per pixel: La = sigma I0 int e^{-sigma (t - t0)} p(theta) F_r(rho) dt,
F_r(rho) = (2 / r^2) int_0^r s rho e^{-sigma sqrt(rho^2 + s^2)} / (rho^2 + s^2)^(3/2) ds
(nested quadrature, no code shared with the bake). The bake takes the radius within
sphere_light_reach of the light (1e-3 of the in-scattering beyond it), so its tolerance
is 1.5e-3 for the exact models and the table's 2e-3 for sun05."""
import math

import numpy as np
import pytest
from scipy import integrate

import _native
from scene_util import floor_bake, per_pixel_to_floor

W, H, FOV, SIGMA, R = 10, 8, 1.1, 0.3, 0.4
LIGHT = np.array([0.3, 0.2, -3.0])
PLANE_Z = -6.0


def bake(**kw):
    return floor_bake(_native.bake, W, H, FOV, PLANE_Z, **(dict(light_positions=[LIGHT],
                                                               light_intensities=[[1.0, 1.0, 1.0]], sigma_t=SIGMA) | kw))


def disk_falloff(rho, r, sigma):
    if r == 0.0:
        return math.exp(-sigma * rho) / (rho * rho)
    f = lambda s: s * rho * math.exp(-sigma * math.hypot(rho, s)) / (rho * rho + s * s) ** 1.5  # noqa: E731
    return 2.0 / (r * r) * integrate.quad(f, 0.0, r, epsabs=0.0, epsrel=1e-11)[0]


def hg(mu, g):
    return (1.0 - g * g) / (4.0 * math.pi * (1.0 + g * g - 2.0 * g * mu) ** 1.5)


def reference(r, g=0.0, profile=None, s=LIGHT):
    def integral(u, t1):
        tc = float(np.dot(s, u))

        def f(t):
            x = t * u
            sx = s - x
            rho = float(np.linalg.norm(sx))
            p = hg(float(np.dot(sx, u)) / rho, g)
            w = 1.0 if profile is None else profile(x)
            return p * w * math.exp(-SIGMA * t) * disk_falloff(rho, r, SIGMA)

        pts = [p for p in (tc - r, tc, tc + r) if 0.0 < p < t1]
        return SIGMA * integrate.quad(f, 0.0, t1, points=pts, epsabs=0.0, epsrel=1e-9, limit=400)[0]

    return per_pixel_to_floor(FOV, W, H, PLANE_Z, integral)


@pytest.fixture(scope="module")
def ref_disk():
    return reference(R)


@pytest.fixture(scope="module")
def ref_point():
    return reference(0.0)


@pytest.mark.parametrize("model, rtol", [("sun05", 2e-3), ("sun05_exact", 1.5e-3), ("quadrature", 1.5e-3),
                                         ("biri06", 2e-3), ("pegoraro10", 1.5e-3)])
def test01_point_light_radius_matches_the_disk(model, rtol, ref_disk, ref_point):
    got = bake(model=model, light_radii=[R])
    np.testing.assert_allclose(got, ref_disk, rtol=rtol)
    # The radius matters here: near the light's image the disk is well below the point.
    assert (1.0 - ref_disk / ref_point).max() > 0.05
    assert np.abs(got / ref_point - 1.0).max() > 0.05


def test02_radius_zero_is_the_point(ref_point):
    np.testing.assert_array_equal(bake(light_radii=[0.0], model="sun05_exact"), bake(model="sun05_exact"))
    np.testing.assert_allclose(bake(model="sun05_exact"), ref_point, rtol=1e-6)


@pytest.mark.parametrize("model", ["biri06", "quadrature"])
def test03_anisotropic_phase(model):
    g = 0.6
    ref = reference(R, g=g)
    np.testing.assert_allclose(bake(model=model, phase="hg", g=g, light_radii=[R]), ref, rtol=3e-3)


def test04_spot_light_radius():
    axis = np.array([0.0, -0.3, -1.0])
    axis /= np.linalg.norm(axis)
    size, blend = 1.6, 0.3
    ch = math.cos(size / 2.0)

    def profile(x):
        v = x - LIGHT
        c = float(np.dot(v, axis)) / float(np.linalg.norm(v))
        if c <= ch:
            return 0.0
        t = min(1.0, (c - ch) / ((1.0 - ch) * blend))
        return c * t * t * (3.0 - 2.0 * t)

    ref = reference(R, profile=profile)
    spots = dict(spot_positions=[LIGHT], spot_axes=[axis], spot_intensities=[[1.0] * 3], spot_size=[size],
                 spot_blend=[blend], spot_radii=[R])
    got = bake(light_positions=np.zeros((0, 3)), light_intensities=np.zeros((0, 3)), model="sun05_exact", **spots)
    lit = ref > 1e-3 * ref.max()  # the cone's edge pixels are where a point's profile is taken (docs)
    np.testing.assert_allclose(got[lit], ref[lit], rtol=3e-3)


def test05_shadows_without_casters_change_nothing(ref_disk):
    got = bake(model="sun05_exact", light_radii=[R], shadows=True, occluder_vertices=np.zeros((0, 3), np.float32),
               occluder_triangles=np.zeros((0, 3), np.int32))
    np.testing.assert_allclose(got, ref_disk, rtol=1.5e-3)


@pytest.mark.parametrize("radii, match", [([-0.1], "radius must be finite and >= 0"),
                                          ([float("nan")], "radius must be finite and >= 0"),
                                          ([float("inf")], "radius must be finite and >= 0"),
                                          ([0.1, 0.2], "light_radii: expected one radius per light")])
def test06_bad_radius_is_refused(radii, match):
    with pytest.raises(ValueError, match=match):
        bake(light_radii=radii)


def test07_spot_radii_need_spots():
    with pytest.raises(ValueError, match="spot_radii needs the spot lights"):
        bake(spot_radii=[0.1])


def test08_huge_radius_and_dense_fog_stay_finite():
    for r, sigma in ((50.0, 0.3), (0.4, 40.0), (1e-9, 0.3)):
        got = bake(light_radii=[r], sigma_t=sigma)
        assert np.all(np.isfinite(got)) and got.min() >= 0.0, (r, sigma)
    # A light far bigger than the scene: the disk's 2 / r^2 bound, far below the point.
    assert bake(light_radii=[50.0]).max() < 0.05 * bake().max()


SIDE = np.array([7.0, 0.2, -3.0])   # beside the view: its rays pass it at 5.2-8.8 m (13-22 radii)


@pytest.fixture(scope="module")
def ref_side():
    return reference(R, s=SIDE), reference(0.0, s=SIDE)


@pytest.mark.parametrize("tol", [0.005, 0.004])
def test09_light_size_tolerance_bounds_the_skipped_radius(tol, ref_side):
    """Rays where the radius changes the light's airlight by less than light_size_tolerance
    take the point's: within that of the disk (and the bake's own 1.5e-3), and skipped on some."""
    disk, point = ref_side
    got = bake(model="sun05_exact", light_positions=[SIDE], light_radii=[R], light_size_tolerance=tol)
    assert (np.abs(got - disk) / disk).max() <= tol + 1.5e-3
    # The rays it skipped take the point's airlight; more of them than at a finer tolerance.
    as_point = bake(model="sun05_exact", light_positions=[SIDE])
    assert np.abs(as_point - point).max() <= 1e-6 * point.max()
    fine = bake(model="sun05_exact", light_positions=[SIDE], light_radii=[R], light_size_tolerance=1e-5)
    skipped = (got == as_point).sum()
    assert skipped > (fine == as_point).sum() and 0 < skipped < got.size, (skipped, (fine == as_point).sum())


@pytest.mark.parametrize("tol", [0.0, -1e-3, 0.006, float("nan")])
def test10_bad_light_size_tolerance_is_refused(tol):
    with pytest.raises(ValueError, match="light_size_tolerance must be in"):
        bake(light_radii=[R], light_size_tolerance=tol)
