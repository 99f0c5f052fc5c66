"""F(u, v) = int_0^v exp(-u tan xi) dxi against mpmath quadrature of the definition."""
import math

import mpmath
import numpy as np
import pytest

import _native


def F_mpmath(u, v):
    return float(mpmath.quad(lambda xi: mpmath.exp(-u * mpmath.tan(xi)), [0, v]))


def random_points(n, seed):
    rng = np.random.default_rng(seed)
    u = np.concatenate([rng.uniform(0, 2, n // 2), rng.uniform(2, 10, n - n // 2)])
    v = rng.uniform(0, math.pi / 2, n)
    return u, v


def test01_exact_matches_mpmath():
    u, v = random_points(40, 1)
    got = _native.special_F(u, v, exact=True)
    want = np.array([F_mpmath(a, b) for a, b in zip(u, v)])
    np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-14)


def test02_table_matches_mpmath():
    # The fast path; special_f.cpp documents 2.6e-4 max, 6.7e-6 mean relative error (256 x 256).
    u, v = random_points(200, 2)
    got = _native.special_F(u, v)
    want = np.array([F_mpmath(a, b) for a, b in zip(u, v)])
    rel = np.abs(got - want) / np.maximum(want, 1e-12)
    assert rel.max() < 1e-3, rel.max()
    assert rel.mean() < 1e-4, rel.mean()


@pytest.mark.parametrize("exact", [True, False])
def test03_F_of_zero_u_is_v(exact):
    v = np.linspace(0, math.pi / 2, 33)
    np.testing.assert_allclose(_native.special_F(0.0, v, exact=exact), v, rtol=1e-10 if exact else 1e-4, atol=1e-12)


def test04_half_pi_is_auxiliary_f():
    # F(u, pi/2) = Ci(u) sin u - (Si(u) - pi/2) cos u (NOTES.md).
    for u in [0.1, 0.7, 2.0, 5.0, 9.0]:
        want = float(mpmath.ci(u) * mpmath.sin(u) - (mpmath.si(u) - mpmath.pi / 2) * mpmath.cos(u))
        assert _native.special_F(u, math.pi / 2, exact=True) == pytest.approx(want, rel=1e-9)


def test05_broadcasting():
    u = np.array([[0.5], [1.5]])
    v = np.array([0.1, 0.2, 0.3])
    out = _native.special_F(u, v, exact=True)
    assert out.shape == (2, 3)
    assert out[1, 2] == pytest.approx(F_mpmath(1.5, 0.3), rel=1e-9)


def test06_domain_errors():
    with pytest.raises(ValueError, match="u"):
        _native.special_F(-1.0, 0.5)
    with pytest.raises(ValueError, match="v"):
        _native.special_F(1.0, 2.0)
    with pytest.raises(ValueError):
        _native.special_F(float("nan"), 0.5)


def test07_table_export():
    t = _native.special_F_table(nu=64, nT=32)
    assert t["data"].dtype == np.float32
    assert t["data"].shape == (64, 32)
    assert np.all(np.isfinite(t["data"]))
