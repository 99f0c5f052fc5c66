"""Environment lighting in Gaussian fog (Fogshop section 4.2, environment.h): T(u) against
scipy's Dawson function and a 2D quadrature of its definition, the average optical depth of a
few Gaussians against a direct quadrature over directions and distances, the far field
against brute force and its bound, and the per-pixel irradiance against the homogeneous one."""
import math

import numpy as np
import pytest
from scipy import integrate, special

import _native


def unit_reference(u):
    u = np.asarray(u, dtype=np.float64)
    safe = np.maximum(u, 1e-300)
    return np.where(u > 0, 0.5 * np.sqrt(np.pi) * special.dawsn(safe) / safe, 0.5 * np.sqrt(np.pi))


def test01_unit_depth_vs_dawsn():
    u = np.concatenate([np.linspace(0.0, 12.0, 20001), np.geomspace(12.0, 1e5, 500)])
    ref = unit_reference(u)
    assert np.max(np.abs(_native.average_depth_unit(u, exact=True) / ref - 1.0)) < 1e-13
    assert np.max(np.abs(_native.average_depth_unit(u) / ref - 1.0)) < 1e-9
    assert _native.average_depth_unit(np.array([0.0]))[0] == pytest.approx(0.5 * math.sqrt(math.pi), rel=1e-15)
    big = 1e4
    assert _native.average_depth_unit(np.array([big]))[0] == pytest.approx(math.sqrt(math.pi) / (4 * big * big),
                                                                            rel=1e-8)


@pytest.mark.parametrize("u", [0.0, 0.4, 1.0, 2.5, 6.0, 11.0])
def test02_unit_depth_vs_2d_quadrature(u):
    # (1/4pi) int_S int_0^inf exp(-|u + t w|^2) dt dw, u on the z axis: the azimuth gives 2 pi.
    val, _ = integrate.dblquad(lambda t, mu: np.exp(-(u * u + 2 * u * t * mu + t * t)), -1.0, 1.0, 0.0, np.inf,
                               epsabs=0.0, epsrel=1e-11)
    assert _native.average_depth_unit(np.array([u]))[0] == pytest.approx(0.5 * val, rel=1e-9)


def test03_average_depth_vs_direct_quadrature():
    # (1/4pi) int_S int_0^Tmax sum_i c_i exp(-a_i^2 |p + t w - b_i|^2) dt dw on a Gauss-Legendre
    # (mu) x uniform (phi) x Simpson (t) grid: the density itself, no line-integral formula.
    b = np.array([[0.0, 0.0, 0.0], [1.5, 0.3, -0.2], [-0.4, 1.0, 0.7]])
    a = np.array([1.0, 2.0, 0.6])
    c = np.array([0.8, 1.5, 0.3])
    mu, wmu = np.polynomial.legendre.leggauss(64)
    nphi = 96
    phi = 2 * np.pi * (np.arange(nphi) + 0.5) / nphi
    t = np.linspace(0.0, 40.0, 8001)
    st = np.sqrt(1 - mu ** 2)
    w = np.stack([st[:, None] * np.cos(phi)[None, :], st[:, None] * np.sin(phi)[None, :],
                  mu[:, None] + 0 * phi[None, :]], -1).reshape(-1, 3)
    weights = (wmu[:, None] * np.full(nphi, 2 * np.pi / nphi)[None, :]).reshape(-1)
    for p in ([0.0, 0.0, 0.0], [0.3, -0.5, 0.2], [4.0, 1.0, -2.0]):
        p = np.array(p)
        total = 0.0
        for k in range(0, len(w), 512):
            x = p[None, None, :] + t[None, :, None] * w[k:k + 512, None, :]
            beta = sum(ci * np.exp(-ai * ai * np.sum((x - bi) ** 2, axis=-1)) for bi, ai, ci in zip(b, a, c))
            total += np.sum(weights[k:k + 512] * integrate.simpson(beta, x=t, axis=1))
        ref = total / (4 * np.pi)
        for exact in (True, False):
            got = _native.rbf_average_depth(centres=b, scales=a, amplitudes=c, points=p[None, :],
                                            exact=exact)["average_depth"][0]
            assert got == pytest.approx(ref, rel=1e-6), (p, exact)
    # beta0 D is added as it is.
    got = _native.rbf_average_depth(centres=b, scales=a, amplitudes=c, points=np.zeros((1, 3)), beta0=0.01,
                                    distance=70.0, exact=True)["average_depth"][0]
    assert got == pytest.approx(0.7 + _native.rbf_average_depth(
        centres=b, scales=a, amplitudes=c, points=np.zeros((1, 3)), exact=True)["average_depth"][0], rel=1e-14)


def cloud(n, seed):
    rng = np.random.default_rng(seed)
    centre = rng.uniform(-20, 20, (10, 3))
    b = centre[np.arange(n) % 10] + rng.uniform(-2, 2, (n, 3))
    return b, rng.uniform(0.5, 3.0, n), rng.uniform(0.0, 0.5, n)


@pytest.mark.parametrize("tol", [1e-2, 1e-3])
def test04_far_field_within_bound(tol):
    b, a, c = cloud(2000, 4)
    rng = np.random.default_rng(5)
    p = np.concatenate([rng.uniform(-25, 25, (1500, 3)), rng.uniform(-150, 150, (1500, 3))])
    ref = _native.rbf_average_depth(centres=b, scales=a, amplitudes=c, points=p, exact=True)["average_depth"]
    out = _native.rbf_average_depth(centres=b, scales=a, amplitudes=c, points=p, tolerance=tol)
    err = np.max(np.abs(out["average_depth"] / ref - 1.0))
    assert err <= tol
    stats = out["stats"]
    assert stats["far_terms"] > 0
    assert stats["near_terms"] + stats["far_terms"] < len(p) * len(a)


@pytest.mark.parametrize("tol", [1e-2, 1e-3])
def test04b_linearised_far_field_within_bound(tol):
    # Dense patches (as a rendered surface's hit points) in a plane through a compact cloud, some
    # coarse enough that linearising every far node over a block would be off by percents: the
    # linear models take far nodes only where their Taylor remainder fits, the error stays <= tol.
    rng = np.random.default_rng(8)
    b = rng.uniform(-1, 1, (500, 3)) * np.array([1.0, 0.5, 1.0])
    a = rng.uniform(2.0, 4.0, 500)
    c = rng.uniform(0.1, 0.5, 500)
    patches = []
    for D in (8.0, 15.0, 25.0):
        for spacing in (0.01, 0.08, 0.3):
            s = spacing * (np.arange(40) - 19.5)
            X, Z = np.meshgrid(D + s, D - 12.0 + s)
            patches.append(np.stack([X.ravel(), np.zeros(X.size), Z.ravel()], -1))
    p = np.concatenate(patches)
    ref = _native.rbf_average_depth(centres=b, scales=a, amplitudes=c, points=p, exact=True)["average_depth"]
    out = _native.rbf_average_depth(centres=b, scales=a, amplitudes=c, points=p, tolerance=tol)
    assert np.max(np.abs(out["average_depth"] / ref - 1.0)) <= tol
    stats = out["stats"]
    assert stats["far_linear_terms"] > stats["points"]  # far nodes went through the linear models
    assert stats["far_terms"] > 0  # ... but not all of them


def test05_band_table_vs_exact_eigenvalues():
    T = np.array([1e-3, 0.05, 0.3, 1.0, 3.0, 7.5, 30.0])
    got = _native.psf_band_eigenvalues(T)
    ref = np.array([_native.psf_eigenvalues(x, 2, "exact") for x in T])
    assert np.max(np.abs(got / ref - 1.0)) < 1e-3
    assert np.max(np.abs(got - ref)) < 2e-6
    assert np.all(_native.psf_band_eigenvalues(np.array([0.0])) == 0.0)


def sky():
    h, w = 32, 64
    v = 1.0 - (np.arange(h) + 0.5) / h
    u = (np.arange(w) + 0.5) / w
    theta = (1.0 - v)[:, None] * np.pi
    ph = (0.5 - u)[None, :] * 2.0 * np.pi
    d = np.stack([np.sin(theta) * np.cos(ph), np.sin(theta) * np.sin(ph), np.cos(theta) + 0 * ph], -1)
    value = 0.3 + 0.2 * np.clip(d[..., 2], 0, 1) + 20.0 * np.exp((d @ np.array([0.36, 0.6, 0.71]) - 1) / 0.01)
    return np.ascontiguousarray(np.stack([value, 0.8 * value, 0.6 * value], -1), dtype=np.float32)


@pytest.mark.parametrize("T", [0.05, 0.7, 2.5, 9.0])
def test06_uniform_depth_equals_homogeneous_ratio(T):
    albedo = np.array([0.9, 0.8, 0.7])
    distance = 40.0
    fog = _native.environment_fog(world=sky(), sigma_t=T / distance, distance=distance, albedo=albedo, sh_order=2,
                                  out_width=8, out_height=4, kind="exact")
    rng = np.random.default_rng(1)
    n = rng.normal(size=(200, 3))
    ew0, ef0 = _native.environment_irradiance(fog["sh_world"], fog["eigenvalues"], fog["transmittance"], albedo, n)
    ew1, ef1 = _native.environment_irradiance_varying(fog["sh_world"], albedo, n, np.full(len(n), T))
    np.testing.assert_allclose(ew1, ew0, rtol=1e-12)
    np.testing.assert_allclose(ef1 / ew1 - 1.0, ef0 / ew0 - 1.0, atol=2e-6, rtol=0)


def camera(width, height):
    cam_to_world = np.diag([-1.0, 1.0, -1.0, 1.0])
    n, f = 0.1, 1000.0
    p = np.zeros((4, 4))
    p[0, 0] = 1.0 / math.tan(math.radians(30.0))
    p[1, 1] = p[0, 0] * width / height
    p[2, 2] = -(f + n) / (f - n)
    p[2, 3] = -2.0 * f * n / (f - n)
    p[3, 2] = -1.0
    return cam_to_world, p


def test07_view_against_points_and_rays():
    W, H = 48, 27
    cam, proj = camera(W, H)
    t = math.tan(math.radians(30.0))
    xs = -((np.arange(W) + 0.5) / W * 2 - 1) * t
    ys = (1 - (np.arange(H) + 0.5) / H * 2) * t * H / W
    X, Y = np.meshgrid(xs, ys)
    d = np.stack([X, Y, np.ones_like(X)], -1)
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    with np.errstate(divide="ignore"):
        depth = np.where(d[..., 1] < -1e-9, -2.0 / d[..., 1], np.inf).astype(np.float32)
    b = np.array([[0.0, 0.5, 12.0], [3.0, -1.0, 20.0], [-4.0, 2.0, 30.0]])
    a = np.array([0.5, 0.8, 0.3])
    c = np.array([0.3, 0.2, 0.1])
    out = _native.environment_rbf_view(cam_to_world=cam, projection=proj, width=W, height=H, clip_start=0.1,
                                       clip_end=1000.0, depth=depth, centres=b, scales=a, amplitudes=c,
                                       beta0=0.01, distance=50.0, tolerance=0.0)
    miss = np.isinf(depth)
    assert miss.any() and (~miss).any()
    # Misses: the Gaussians' optical depth from the near plane (t = 0.1 / cos) to infinity.
    dm = d[miss]
    t0 = 0.1 / dm[:, 2]
    medium = _native.RbfMedium(b, a, c, beta0=0.0)
    ref = medium.optical_depth_ray(dm * t0[:, None], dm, np.full(len(dm), np.inf), culled=False)
    # (the bake culls: <= 1e-7 per Gaussian the ray stays away from)
    np.testing.assert_allclose(out["world_optical_depth"][miss], ref, rtol=1e-6, atol=3e-7)
    assert np.all(out["world_optical_depth"][~miss] == 0.0)
    # Hits: Tbar at the first hit; misses carry beta0 D.
    p = d[~miss] * depth[~miss].astype(np.float64)[:, None]
    ref = _native.rbf_average_depth(centres=b, scales=a, amplitudes=c, points=p, beta0=0.01, distance=50.0,
                                    exact=True)["average_depth"]
    np.testing.assert_allclose(out["average_depth"][~miss], ref, rtol=1e-6)
    assert np.all(out["average_depth"][miss] == pytest.approx(0.5))


def test08_errors():
    b, a, c = np.zeros((1, 3)), np.ones(1), np.ones(1)
    with pytest.raises(ValueError):
        _native.average_depth_unit(np.array([-1.0]))
    with pytest.raises(ValueError):
        _native.rbf_average_depth(centres=b, scales=a, amplitudes=c, points=np.array([[np.nan, 0, 0]]))
    with pytest.raises(ValueError):
        _native.rbf_average_depth(centres=b, scales=a, amplitudes=c, points=np.zeros((1, 3)), tolerance=-1.0)
    with pytest.raises(ValueError):
        _native.rbf_average_depth(centres=b, scales=-a, amplitudes=c, points=np.zeros((1, 3)))
    with pytest.raises(ValueError):
        _native.rbf_average_depth(centres=b, scales=a, amplitudes=c, points=np.zeros((1, 3)), distance=-1.0)
    with pytest.raises(ValueError):
        _native.environment_irradiance_varying(np.ones((9, 3)), np.ones(3), np.ones((2, 3)), np.array([0.1, np.nan]))
    with pytest.raises(ValueError):
        _native.environment_irradiance_varying(np.ones((9, 3)), np.ones(3), np.zeros((1, 3)), np.array([0.1]))
    with pytest.raises(ValueError):
        _native.psf_band_eigenvalues(np.array([-1.0]))
