"""Phase functions, Biri 2006 and Hoffman-Preetham against scipy quadrature."""
import math

import numpy as np
import pytest
from scipy import integrate

import _native

PHASES = [("isotropic", 0.0), ("rayleigh", 0.0), ("hazy_mie", 0.0), ("murky_mie", 0.0),
          ("hg", -0.9), ("hg", -0.3), ("hg", 0.5), ("hg", 0.9)]


@pytest.mark.parametrize("name,g", PHASES)
def test01_phase_normalised(name, g):
    f = lambda theta: 2 * math.pi * math.sin(theta) * float(_native.phase(name, math.cos(theta), g))
    pts = [1e-3, 1e-2, 0.1, 0.5]
    total = integrate.quad(f, 0.0, math.pi, points=pts, epsabs=0, epsrel=1e-11, limit=500)[0]
    assert total == pytest.approx(1.0, rel=1e-9)


def test02_phase_errors():
    with pytest.raises(ValueError):
        _native.phase("mie", 0.0)
    with pytest.raises(ValueError):
        _native.phase("hg", 0.0, g=1.0)
    with pytest.raises(ValueError):
        _native.phase("hg", 1.5)


def scipy_airlight(name, g, sigma, Dsv, c, Dvp):
    a, h = Dsv * c, Dsv * math.sqrt(max(0.0, 1 - c * c))

    def f(x):
        d = math.hypot(x - a, h)
        return float(_native.phase(name, (a - x) / d, g)) * math.exp(-sigma * (d + x)) / (d * d)
    pts = [p for p in (a - 4 * h, a - h, a, a + h) if 0 < p < Dvp]
    return sigma * integrate.quad(f, 0.0, Dvp, points=pts or None, epsabs=0, epsrel=1e-10, limit=500)[0]


@pytest.mark.parametrize("name,g", PHASES)
def test03_biri_vs_scipy(name, g):
    rng = np.random.default_rng(4)
    n = 15
    Dsv = rng.uniform(0.5, 20, n)
    sigma = 10 ** rng.uniform(-3, 0.5, n) / Dsv
    c = rng.uniform(-0.99, 0.99, n)
    Dvp = rng.uniform(0.2, 50, n)
    want = np.array([scipy_airlight(name, g, *a) for a in zip(sigma, Dsv, c, Dvp)])
    quad = _native.airlight_quadrature(sigma, Dsv, c, Dvp, phase=name, g=g)
    exact = _native.biri06_airlight(sigma, Dsv, c, Dvp, phase=name, g=g, exact=True)
    table = _native.biri06_airlight(sigma, Dsv, c, Dvp, phase=name, g=g)
    np.testing.assert_allclose(quad, want, rtol=1e-7)
    np.testing.assert_allclose(exact, want, rtol=1e-7)
    np.testing.assert_allclose(table, want, rtol=5e-3)


def test04_biri_errors():
    with pytest.raises(ValueError):
        _native.biri06_airlight(-1.0, 1.0, 0.0, 1.0)
    with pytest.raises(ValueError):
        _native.biri06_airlight(0.1, 1.0, 0.0, float("nan"))
    with pytest.raises(ValueError):
        _native.biri06_airlight(0.1, 1.0, 0.0, 1.0, phase="nope")


def test05_hoffman_vs_scipy():
    bR = np.array(_native.hoffman02_rayleigh_rgb(1e-3))
    bM = np.array([2e-3, 2e-3, 2e-3])
    E = np.array([1.0, 0.9, 0.7])
    sun = np.array([0.3, -0.2, -1.0]); sun /= np.linalg.norm(sun)
    for view in ([0, 0, 1], [1, 0, 0], [0.2, 0.1, -1]):
        view = np.array(view, float); view /= np.linalg.norm(view)
        cos_theta = -sun @ view
        out = _native.hoffman02(cos_theta, 800.0, bR, bM, g=0.6, E_sun=E)
        for ch in range(3):
            def f(x):
                pR = float(_native.phase("rayleigh", cos_theta))
                pM = float(_native.phase("hg", cos_theta, 0.6))
                return (bR[ch] * pR + bM[ch] * pM) * E[ch] * math.exp(-(bR[ch] + bM[ch]) * x)
            want = integrate.quad(f, 0, 800.0, epsabs=0, epsrel=1e-12)[0]
            assert out["L_in"][ch] == pytest.approx(want, rel=1e-10)
            assert out["F_ex"][ch] == pytest.approx(math.exp(-(bR[ch] + bM[ch]) * 800.0), rel=1e-14)
    toward = _native.hoffman02(1.0, 800.0, bR, bM, g=0.6)["L_in"]
    away = _native.hoffman02(-1.0, 800.0, bR, bM, g=0.6)["L_in"]
    assert np.all(toward > 5 * away)
