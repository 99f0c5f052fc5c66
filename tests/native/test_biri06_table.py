"""_native.biri06_table (the Biri 2006 G table the preview uploads to the GPU) against
independent references: the isotropic identity G(lambda, T) = F(lambda, atan T) / (2 pi)
with Sun 2005's exact F, and scipy quadrature of G for Henyey-Greenstein g = 0.6."""
import math

import numpy as np
import pytest
from scipy import integrate

import _native


def _nodes(table, rows, cols):
    """(lambda, T, G from the stored Q) at the table's nodes (rows i, cols j)."""
    nl, nT, K, k = table["nl"], table["nT"], table["K"], table["k"]
    out = []
    for i in rows:
        s = i / (nl - 1)
        lam = k * s * s / (1.0 - s * s)
        for j in cols:
            w = j / (nT - 1)
            T = w / ((1.0 - w) * (K + lam))
            out.append((lam, T, float(table["data"][i, j]) * w / (K + lam)))
    return out


def test01_isotropic_nodes_match_special_F():
    table = _native.biri06_table("isotropic", 0.0)
    assert table["data"].shape == (256, 256) and table["data"].dtype == np.float32
    assert table["phase"] == "isotropic"
    for lam, T, G in _nodes(table, range(0, 255, 17), range(1, 255, 23)):
        ref = float(_native.special_F(lam, math.atan(T), exact=True)) / (2.0 * math.pi)
        assert G == pytest.approx(ref, rel=2e-6), (lam, T)


def test02_hg_nodes_match_quadrature():
    g = 0.6
    table = _native.biri06_table("hg", g)
    assert table["g"] == pytest.approx(g) and table["K"] == pytest.approx(1.0 / (1.0 - g))
    for lam, T, G in _nodes(table, (0, 40, 128, 200), (1, 30, 128, 250)):
        def f(theta):
            p = float(_native.phase("hg", math.cos(theta), g))
            return p * math.exp(-lam * math.tan(0.5 * theta))
        ref = integrate.quad(f, 0.0, 2.0 * math.atan(T), epsabs=0, epsrel=1e-11, limit=400)[0]
        assert G == pytest.approx(ref, rel=2e-6), (lam, T)


def test03_errors():
    with pytest.raises(ValueError):
        _native.biri06_table("mie", 0.0)
    with pytest.raises(ValueError):
        _native.biri06_table("hg", 1.0)
    with pytest.raises(ValueError):
        _native.biri06_table("hg", 0.5, nl=1)
