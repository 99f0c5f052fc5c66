"""Gaussian (RBF) medium: optical depth against mpmath and scipy quadrature, culling bound,
the Fogshop airlight against the quadrature reference and against Sun 2005, bad input."""
import math

import mpmath
import numpy as np
import pytest
from scipy import integrate

import _native

mpmath.mp.dps = 40


def mp_erf_diff(x1, x2):
    """erf(x2) - erf(x1) in 40 digits; erfc form on one side of 0 (erf itself rounds to 1 there)."""
    x1, x2 = mpmath.mpf(x1), mpmath.mpf(x2)
    if x1 >= 0:
        return mpmath.erfc(x1) - mpmath.erfc(x2)
    if x2 <= 0:
        return mpmath.erfc(-x2) - mpmath.erfc(-x1)
    return mpmath.erf(x2) - mpmath.erf(x1)


def mp_line_integral(c, a, b, p, q):
    """eq. 31 for one Gaussian in 40-digit arithmetic (the independent reference)."""
    p, q, b = (mpmath.matrix([mpmath.mpf(float(x)) for x in v]) for v in (p, q, b))
    d = q - p
    L = mpmath.sqrt(sum(x * x for x in d))
    r = d / L
    rel = b - p
    ts = sum(rel[k] * r[k] for k in range(3))
    h2 = sum(x * x for x in rel) - ts * ts
    a, c = mpmath.mpf(a), mpmath.mpf(c)
    return c * mpmath.sqrt(mpmath.pi) / (2 * a) * mpmath.exp(-a * a * h2) * mp_erf_diff(-a * ts, a * (L - ts))


def test01_erf_diff_tails_vs_mpmath():
    rng = np.random.default_rng(1)
    x1 = np.concatenate([rng.uniform(-25, 25, 400), rng.uniform(4, 25, 200), -rng.uniform(4, 25, 200)])
    w = 10.0 ** rng.uniform(-9, 1, x1.size)
    x2 = x1 + w
    got = _native.erf_diff(x1, x2)
    worst = 0.0
    for a, b, g in zip(x1, x2, got):
        ref = mp_erf_diff(a, b)
        if abs(ref) < 1e-300:
            continue
        worst = max(worst, float(abs((g - ref) / ref)))
    print(f"erf_diff vs mpmath: worst relative error {worst:.2e}")
    assert worst < 1e-12


@pytest.mark.parametrize("a", [1e-3, 0.3, 1.0, 30.0, 1e3])
def test02_optical_depth_vs_mpmath(a):
    """Segments in the far tails on one side (erf differences cancel), beside, through."""
    rng = np.random.default_rng(int(a * 1000) % 97)
    b = np.array([0.5, -1.0, 2.0])
    m = _native.RbfMedium(b[None, :], [a], [0.8])
    ps, qs = [], []
    for k in range(40):
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        side = np.cross(d, rng.normal(size=3))
        side /= np.linalg.norm(side)
        h = rng.uniform(0, 4) / a
        t0 = (rng.uniform(3, 8) if k % 2 else rng.uniform(-8, 8)) / a
        length = 10 ** rng.uniform(-2, 2) / a
        p = b + h * side + t0 * d
        ps.append(p)
        qs.append(p + length * d)
    ps, qs = np.array(ps), np.array(qs)
    got = m.optical_depth(ps, qs, culled=False)
    got_culled = m.optical_depth(ps, qs)
    for p, q, g, gc in zip(ps, qs, got, got_culled):
        ref = mp_line_integral(0.8, a, b, p, q)
        if ref < 1e-290:
            continue
        # h comes from rounded inputs: allow the conditioning of exp(-a^2 h^2) (a h ~ 4).
        assert abs(g - ref) <= 1e-10 * ref, (p, q, g, float(ref))
        assert abs(gc - ref) <= 1e-10 * ref + m.cull_eps


def test03_optical_depth_vs_scipy_quad_many():
    rng = np.random.default_rng(5)
    n = 40
    b = rng.uniform(-5, 5, (n, 3))
    a = 10 ** rng.uniform(-1, 0.5, n)
    c = rng.uniform(0, 0.5, n)
    m = _native.RbfMedium(b, a, c, beta0=0.01)
    p = np.array([-7.0, 0.3, -0.2])
    q = np.array([6.0, -0.5, 1.0])
    r = (q - p) / np.linalg.norm(q - p)
    L = np.linalg.norm(q - p)
    dens = lambda t: float(m.density((p + t * r)[None, :])[0])
    ref, _ = integrate.quad(dens, 0, L, epsabs=0, epsrel=1e-12, limit=500)
    got = m.optical_depth(p[None], q[None])[0]
    assert got == pytest.approx(ref, rel=1e-9)
    # Infinite ray without background: finite; with background: inf.
    m0 = _native.RbfMedium(b, a, c)
    t_inf = m0.optical_depth_ray(p[None], r[None], [np.inf])[0]
    ref_inf, _ = integrate.quad(lambda t: float(m0.density((p + t * r)[None, :])[0]), 0, np.inf, epsrel=1e-11,
                                limit=500)
    assert t_inf == pytest.approx(ref_inf, rel=1e-8)
    assert np.isinf(m.optical_depth_ray(p[None], r[None], [np.inf])[0])


def test04_culling_bound():
    rng = np.random.default_rng(9)
    n = 3000
    m = _native.RbfMedium(rng.uniform(-50, 50, (n, 3)), 10 ** rng.uniform(-1.5, 1, n), rng.uniform(0, 1, n),
                          cull_eps=1e-6)
    p = rng.uniform(-50, 50, (500, 3))
    q = rng.uniform(-50, 50, (500, 3))
    full = m.optical_depth(p, q, culled=False)
    culled = m.optical_depth(p, q)
    drop = full - culled
    print(f"culling: worst drop {drop.max():.2e} (bound n eps = {n * m.cull_eps:.1e})")
    assert np.all(drop >= -1e-12 * full)
    assert np.all(drop <= n * m.cull_eps)


def test05_empty_medium_is_sun05():
    m = _native.RbfMedium(np.zeros((0, 3)), [], [], beta0=0.04)
    rng = np.random.default_rng(2)
    d = rng.normal(size=(200, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    Dvp = np.where(rng.uniform(size=200) < 0.3, np.inf, rng.uniform(0.1, 50, 200))
    v = np.array([1.0, 2.0, 3.0])
    s = np.array([4.0, -1.0, 5.0])
    got = m.airlight(s, v, d, Dvp)
    Dsv = np.linalg.norm(s - v)
    ref = _native.sun05_airlight(0.04, Dsv, d @ (s - v) / Dsv, Dvp, model="sun05")
    np.testing.assert_allclose(got, ref, rtol=1e-12)
    two = m.airlight(np.stack([s, s + 1]), v, d, Dvp)
    assert two.shape == (200, 2)
    np.testing.assert_allclose(two[:, 0], ref, rtol=1e-12)


def test06_single_gaussian_airlight_vs_scipy():
    """Fogshop and the native quadrature against an independent scipy quadrature of eq. 2."""
    b = np.array([0.0, 0.0, 10.0])
    a, c = 0.5, 0.05
    m = _native.RbfMedium(b[None], [a], [c])
    v = np.zeros(3)
    s = np.array([0.0, 12.0, 10.0])
    dirs = np.array([[0.0, 0.0, 1.0], [0.05, 0.02, 1.0], [0.0, 0.1, 1.0]])
    dirs /= np.linalg.norm(dirs, axis=1)[:, None]
    Dvp = np.array([np.inf, 30.0, np.inf])
    fog = m.airlight(s, v, dirs, Dvp)
    quad = m.airlight(s, v, dirs, Dvp, model="quadrature")
    for j, r in enumerate(dirs):
        def f(t):
            x = v + t * r
            T = m.optical_depth(np.stack([s, v]), np.stack([x, x]), culled=False).sum() if t > 0 else 0.0
            return float(m.density(x[None])[0]) / (4 * math.pi * np.sum((x - s) ** 2)) * math.exp(-T)
        ref, _ = integrate.quad(f, 0, min(Dvp[j], 40.0), points=[10.0], epsrel=1e-10, limit=200)
        assert quad[j] == pytest.approx(ref, rel=1e-6)
        assert fog[j] == pytest.approx(ref, rel=0.05)
        print(f"ray {j}: fogshop {fog[j]:.6e} reference {ref:.6e} rel err {fog[j] / ref - 1:+.4f}")


def test07_bad_input():
    with pytest.raises(ValueError, match="not finite"):
        _native.RbfMedium([[np.nan, 0, 0]], [1.0], [1.0])
    with pytest.raises(ValueError, match="scale"):
        _native.RbfMedium([[0, 0, 0]], [0.0], [1.0])
    with pytest.raises(ValueError, match="amplitude"):
        _native.RbfMedium([[0, 0, 0]], [1.0], [-1.0])
    with pytest.raises(ValueError, match="beta0"):
        _native.RbfMedium([[0, 0, 0]], [1.0], [1.0], beta0=-0.1)
    with pytest.raises(ValueError, match="expected shape"):
        _native.RbfMedium([[0, 0, 0]], [1.0, 2.0], [1.0])
    with pytest.raises(ValueError, match=r"\(N, 3\)"):
        _native.RbfMedium([[0, 0]], [1.0], [1.0])
    m = _native.RbfMedium([[0, 0, 0]], [1.0], [1.0])
    assert len(m) == 1
    with pytest.raises(ValueError, match="Dvp"):
        m.airlight([1, 1, 1], [0, 0, -5], [[0, 0, 1]], [-1.0])
    with pytest.raises(ValueError, match="model"):
        m.airlight([1, 1, 1], [0, 0, -5], [[0, 0, 1]], [1.0], model="nope")
    with pytest.raises(ValueError, match="zero"):
        m.airlight([1, 1, 1], [0, 0, -5], [[0, 0, 0]], [1.0])
    with pytest.raises(ValueError):
        m.optical_depth([[0, 0, 0]], [[1, 1, 1], [2, 2, 2]])
