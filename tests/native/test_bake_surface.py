"""Surface shading in the bake (Sun 2005 eq. 13-19; native/bake/surface_pass.h): per-light
attenuation e^{-sigma_t |s - p|} and the Lambert glow albedo I0 sigma_t G(T, theta_s) /
(2 pi^2 D) at the first hit, checked per pixel against values computed here from the depth
pass and the scene (p, the floor normal, D, theta_s), with G by an independent scipy
quadrature of eq. 16 (e^{-T cos g} [F(T sin g, pi/2) - F(T sin g, g/2)] with F integrated
too, the azimuth integral of cos(theta_i) numerically: reference_util.G_ref). Also: surface=False leaves the bake
unchanged and adds nothing; pixels without a hit get attenuation 1 and no glow."""
import math

import numpy as np
import pytest
from scipy import integrate

import _native
from reference_util import G_ref, hg
from scene_surface import ALBEDO, FOV, H, POINT_I, POINT_POS, SIGMA_T, SPOT_POS, W, hit_points, scene
from scene_util import pixel_dirs_camera


@pytest.fixture(scope="module")
def baked():
    kw, R = scene()
    return _native.bake(**kw), R


def test01_attenuation_per_light(baked):
    result, R = baked
    att = result["surface_attenuation"]
    assert att.shape == (2, H, W, 3) and att.dtype == np.float32
    p = hit_points(result, R)
    hit = np.isfinite(result["depth"])
    assert hit.sum() > 0.5 * W * H
    for l, s in enumerate(POINT_POS):
        D = np.linalg.norm(s - p[hit], axis=-1)
        expected = np.exp(-SIGMA_T * D)
        for c in range(3):
            np.testing.assert_allclose(att[l][hit][:, c], expected, rtol=2e-5)
        assert np.all(att[l][~hit] == 1.0)


def test02_glow_against_scipy(baked):
    result, R = baked
    glow = result["surface_glow"]
    assert glow.shape == (H, W, 3)
    p = hit_points(result, R)
    hit = np.isfinite(result["depth"])
    assert np.all(glow[~hit] == 0.0)
    rng = np.random.default_rng(3)
    pixels = np.argwhere(hit)[rng.choice(int(hit.sum()), 4, replace=False)]
    for j, i in pixels:
        total = np.zeros(3)
        for s, I0 in zip(POINT_POS, POINT_I):
            v = s - p[j, i]
            D = float(np.linalg.norm(v))
            theta = math.acos(v[2] / D)  # floor normal +z (faces the camera above it)
            total += I0 * SIGMA_T * G_ref(SIGMA_T * D, theta) / (2 * math.pi ** 2 * D)
        expected = np.array(ALBEDO) * total
        # Table error (sun05_surface.cpp): max 3.1e-3 relative.
        np.testing.assert_allclose(glow[j, i], expected, rtol=4e-3)


def test03_surface_off_is_unchanged(baked):
    result, _ = baked
    kw, _ = scene(surface=False)
    plain = _native.bake(**kw)
    assert "surface_attenuation" not in plain and "surface_glow" not in plain
    np.testing.assert_array_equal(plain["airlight"], result["airlight"])
    np.testing.assert_array_equal(plain["transmittance"], result["transmittance"])


def test04_spot_lights_attenuated_after_points():
    kw, R = scene(spots=True)
    result = _native.bake(**kw)
    att = result["surface_attenuation"]
    assert att.shape[0] == 3
    p = hit_points(result, R)
    hit = np.isfinite(result["depth"])
    D = np.linalg.norm(SPOT_POS[0] - p[hit], axis=-1)
    np.testing.assert_allclose(att[2][hit][:, 0], np.exp(-SIGMA_T * D), rtol=2e-5)
    # Spot lights add their glow (SpotGlowModel, checked per pixel in test_surface_glow_phase.py).
    kw0, _ = scene()
    assert np.all(result["surface_glow"] >= _native.bake(**kw0)["surface_glow"])
    assert np.any(result["surface_glow"] > _native.bake(**kw0)["surface_glow"])


def test05_no_fog_is_neutral():
    kw, _ = scene()
    kw["sigma_t"] = 0.0
    result = _native.bake(**kw)
    assert np.all(result["surface_attenuation"] == 1.0)
    assert np.all(result["surface_glow"] == 0.0)


def test06_gaussian_fog_attenuation_uses_the_exact_optical_depth():
    """With fog objects (Gaussians), the attenuation from each light to the hit is
    exp(-optical depth through beta0 + the Gaussians) (Fogshop's T(s, p)), checked against
    RbfMedium.optical_depth without culling; the glow follows it too (test_surface_glow_phase.py)."""
    kw, R = scene()
    centres = np.array([[0.0, 0.5, 1.0], [-1.5, 2.0, 0.5], [1.0, -1.0, 0.3]])
    scales = np.array([0.8, 1.2, 0.6])
    amplitudes = np.array([0.6, 0.3, 0.9])
    kw.update(rbf_centres=centres, rbf_scales=scales, rbf_amplitudes=amplitudes)
    result = _native.bake(**kw)
    p = hit_points(result, R)
    hit = np.isfinite(result["depth"])
    medium = _native.RbfMedium(centres, scales, amplitudes, beta0=SIGMA_T)
    for l, s in enumerate(POINT_POS):
        q = p[hit]
        T = medium.optical_depth(np.repeat(s[None, :], len(q), axis=0), q, culled=False)
        np.testing.assert_allclose(result["surface_attenuation"][l][hit][:, 0], np.exp(-T), rtol=1e-5, atol=1e-7)
        # The Gaussians make a difference here (else this test shows nothing).
        assert np.max(np.abs(np.exp(-T) - np.exp(-SIGMA_T * np.linalg.norm(q - s, axis=-1)))) > 0.05
    kw0, _ = scene()
    assert not np.allclose(result["surface_glow"], _native.bake(**kw0)["surface_glow"], rtol=1e-3)


def test07_phong_gloss_glow_against_scipy():
    """surface_phong_exponent = n: (n + 2)/(2 pi) albedo I0 sigma_t Gn(T, theta') / (2 pi D) summed
    over the point lights, theta' from the view direction mirrored about the floor normal."""
    n = 20.0
    kw, R = scene()
    result = _native.bake(**kw, surface_phong_exponent=n)
    gloss = result["surface_gloss_glow"]
    assert gloss.shape == (H, W, 3)
    d = pixel_dirs_camera(FOV, W, H) @ R.T
    p = hit_points(result, R)
    hit = np.isfinite(result["depth"])
    rng = np.random.default_rng(5)
    for j, i in np.argwhere(hit)[rng.choice(int(hit.sum()), 3, replace=False)]:
        r = d[j, i] * np.array([1.0, 1.0, -1.0])  # mirrored about the floor normal +z
        total = np.zeros(3)
        for s, I0 in zip(POINT_POS, POINT_I):
            v = s - p[j, i]
            D = float(np.linalg.norm(v))
            theta = math.acos(min(1.0, max(-1.0, float(r @ v) / D)))
            total += I0 * (n + 2) / (2 * math.pi) * SIGMA_T * G_ref(SIGMA_T * D, theta, n) / (2 * math.pi * D)
        # Gn table (64 x 64) error: max 1.4e-2 relative (sun05_surface.cpp).
        np.testing.assert_allclose(gloss[j, i], np.array(ALBEDO) * total, rtol=2e-2)
    # The Lambert outputs do not change with the glossy option; bad exponents are refused.
    np.testing.assert_array_equal(result["surface_glow"], _native.bake(**kw)["surface_glow"])
    with pytest.raises(ValueError, match="surface_phong_exponent"):
        _native.bake(**kw, surface_phong_exponent=0.5)


def _sun_scene(fog_top, phase="isotropic", g=0.0):
    kw, R = scene()
    kw.update(light_positions=np.zeros((0, 3)), light_intensities=np.zeros((0, 3)),
              sun_directions=np.array([[-0.5, 0.3, -0.8]]), sun_irradiances=np.array([[3.0, 2.0, 1.0]]),
              fog_top=fog_top, phase=phase, g=g, model="sun05" if phase == "isotropic" else "biri06")
    return kw, R


def test08_sun_glow_without_top_is_e_over_4pi():
    """Unbounded fog, isotropic phase, unattenuated sun (Hoffman-Preetham): every direction
    brings sigma_s E / (4 pi) x int_0^inf e^{-sigma t} dt = albedo E / (4 pi), so the Lambert
    glow per unit diffuse colour is albedo E / (4 pi) on every surface."""
    kw, R = _sun_scene(math.inf)
    result = _native.bake(**kw)
    hit = np.isfinite(result["depth"])
    expect = np.array(ALBEDO) * np.array([3.0, 2.0, 1.0]) / (4 * math.pi)
    np.testing.assert_allclose(result["surface_glow"][hit], np.broadcast_to(expect, (int(hit.sum()), 3)), rtol=1e-5)
    assert np.all(result["surface_glow"][~hit] == 0.0)


def test09_sun_glow_in_a_layer_against_scipy():
    """A sun in a fog layer below fog_top, Henyey-Greenstein g = 0.5, the floor (normal +z) at
    optical depth tau = sigma (top - 0): Q = (1/pi) int_{w.z > 0} p(l.w) sigma G(w) w.z dw, with
    sigma G the path integral int_0^{tau/mu} e^{-t} e^{-(tau - mu t)/mu_s} dt done by scipy
    here (sigma = 1 units). Table error <= 1e-2 of the glow (sunlight_glow.cpp)."""
    top, g = 2.5, 0.5
    kw, R = _sun_scene(top, "hg", g)
    result = _native.bake(**kw)
    hit = np.isfinite(result["depth"])
    d = np.array([-0.5, 0.3, -0.8])
    l = -d / np.linalg.norm(d)
    mu_s = l[2]
    tau = SIGMA_T * top

    def sigma_G(mu):
        return integrate.quad(lambda t: math.exp(-t - (tau - mu * t) / mu_s), 0.0, tau / mu, epsrel=1e-10)[0]

    def inner(th):
        mu, r = math.cos(th), math.sin(th)
        f = integrate.quad(lambda ph: hg(r * (l[0] * math.cos(ph) + l[1] * math.sin(ph)) + mu * l[2], g),
                           0.0, 2 * math.pi, epsrel=1e-9, limit=200)[0]
        return f * sigma_G(mu) * mu * r

    Q = integrate.quad(inner, 0.0, math.pi / 2, epsrel=1e-8, limit=200)[0] / math.pi
    expect = np.array(ALBEDO) * np.array([3.0, 2.0, 1.0]) * Q
    glow = result["surface_glow"][hit]
    np.testing.assert_allclose(glow, np.broadcast_to(expect, glow.shape), rtol=1e-2)
    # The glow is real here (not a rounding of zero), and the sun's attenuation is unchanged.
    assert Q > 1e-3
    np.testing.assert_allclose(result["surface_attenuation"][0][hit][:, 0], math.exp(-tau / mu_s), rtol=1e-5)


def test10_sun_gloss_glow_against_scipy():
    """surface_phong_exponent = n with a sun in the layer: the glossy glow per unit glossy colour
    (n + 2)/(2 pi) int L_in(w) max(0, r.w)^n dw, r the view direction mirrored about the floor
    normal, L_in = albedo E p(l.w) sigma G(w) with sigma G the path integral done by scipy
    (sigma = 1 units), in coordinates about r. Table error <= 2e-2 (sunlight_glow.cpp)."""
    top, g, n = 2.5, 0.5, 20.0
    kw, R = _sun_scene(top, "hg", g)
    result = _native.bake(**kw, surface_phong_exponent=n)
    hit = np.isfinite(result["depth"])
    dirs = pixel_dirs_camera(FOV, W, H) @ R.T
    d = np.array([-0.5, 0.3, -0.8])
    l = -d / np.linalg.norm(d)
    mu_s, tau = l[2], SIGMA_T * top

    def sigma_G(mu):
        end = tau / mu if mu > 0 else np.inf
        return integrate.quad(lambda t: math.exp(-t - (tau - mu * t) / mu_s), 0.0, end, epsrel=1e-10)[0]

    rng = np.random.default_rng(2)
    for j, i in np.argwhere(hit)[rng.choice(int(hit.sum()), 2, replace=False)]:
        r = dirs[j, i] * np.array([1.0, 1.0, -1.0])
        r = r / np.linalg.norm(r)
        a = np.cross(r, [1.0, 0.0, 0.0])
        a /= np.linalg.norm(a)
        b = np.cross(r, a)

        def inner(alpha):
            def f(beta):
                w = math.cos(alpha) * r + math.sin(alpha) * (math.cos(beta) * a + math.sin(beta) * b)
                return hg(float(l @ w), g) * sigma_G(float(w[2]))
            return integrate.quad(f, 0.0, 2 * math.pi, epsrel=1e-7, limit=100)[0] * math.cos(alpha) ** n * math.sin(alpha)

        lobe = integrate.quad(inner, 0.0, math.pi / 2, points=[0.2, 0.5], epsrel=1e-7, limit=100)[0]
        expect = np.array(ALBEDO) * np.array([3.0, 2.0, 1.0]) * (n + 2) / (2 * math.pi) * lobe
        np.testing.assert_allclose(result["surface_gloss_glow"][j, i], expect, rtol=2e-2)
        assert lobe > 1e-4
