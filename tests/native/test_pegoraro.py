"""Pegoraro et al. 2010: the complex exponential integral against mpmath, the closed form
against the quadrature references (point lights with every phase, spot lights, any
polynomial light distribution), the Sun 2005 exact model, and the bake's spot fast path
against its quadrature path. The relative errors found are printed (pytest -s)."""
import math

import mpmath as mp
import numpy as np
import pytest

import _native
from scene_util import camera_matrix, perspective, plane_z, rotation_x


def e1_reference(z):
    """mpmath's E1 on the principal branch; on the cut the sign of Im z (-0.0 too) picks the side."""
    r = complex(mp.e1(mp.mpc(z.real, z.imag)))
    if z.imag == 0.0 and z.real < 0.0 and math.copysign(1.0, z.imag) < 0.0:
        r = r.conjugate()   # mpmath gives the upper side (-Ei(x) - i pi) for a real argument
    return r


def test01_complex_e1_matches_mpmath():
    mp.mp.dps = 30
    zs = [r * np.exp(1j * t) for r in (1e-10, 1e-4, 0.3, 1.0, 3.0, 4.99, 5.01, 8.0, 20.0, 39.0, 41.0, 100.0, 700.0)
          for t in np.linspace(-math.pi, math.pi, 41)]
    # Near and on the branch cut (both sides), near the imaginary axis, large |z|.
    zs += [complex(-x, s * y) for x in (0.5, 3.0, 7.0, 30.0, 45.0, 80.0) for y in (1e-300, 1e-12, 1e-3, 0.5)
           for s in (1, -1)]
    zs += [complex(-x, 0.0) for x in (0.5, 7.0, 45.0)] + [complex(-x, -0.0) for x in (0.5, 7.0, 45.0)]
    zs += [complex(1e-3, y) for y in (-50.0, -6.0, 6.0, 50.0)] + [complex(690.0, -3.0), complex(400.0, 400.0)]   # E1 ~ e^{-690}: still a normal double
    zs = np.array(zs)
    got = _native.complex_e1(zs)
    ref = np.array([e1_reference(z) for z in zs])
    rel = np.abs(got - ref) / np.abs(ref)
    worst = int(np.argmax(rel))
    print(f"complex E1: {len(zs)} points, max rel err {rel.max():.2e} at z = {zs[worst]}")
    assert np.all(np.isfinite(got))
    assert rel.max() < 1e-11
    # The branch: E1(-x +- i0) = -Ei(x) -+ i pi.
    assert _native.complex_e1(np.array([complex(-2.0, 0.0)]))[0].imag == pytest.approx(-math.pi)
    assert _native.complex_e1(np.array([complex(-2.0, -0.0)]))[0].imag == pytest.approx(math.pi)


def random_point_rays(n, seed):
    rng = np.random.default_rng(seed)
    s = 10 ** rng.uniform(-2, 0.5, n)
    D = 10 ** rng.uniform(-1, 1.5, n)
    c = rng.uniform(-1, 1, n)
    V = np.where(rng.uniform(size=n) < 0.3, np.inf, 10 ** rng.uniform(-1, 2, n))
    return s, D, c, V


def test02_isotropic_equals_sun05_exact():
    s, D, c, V = random_point_rays(400, 1)
    a = _native.pegoraro10_airlight(s, D, c, V, "isotropic", 0.0)
    b = _native.sun05_airlight(s, D, c, V, "sun05_exact")
    rel = np.abs(a - b) / b
    print(f"pegoraro10 isotropic vs sun05_exact: max rel {rel.max():.2e}")
    assert rel.max() < 1e-8


@pytest.mark.parametrize("phase,g,order,tol", [
    ("isotropic", 0.0, -1, 1e-9), ("rayleigh", 0.0, -1, 1e-9), ("hazy_mie", 0.0, -1, 1e-9),
    ("murky_mie", 0.0, -1, 1e-9),                   # exact polynomial of order 32
    ("hg", 0.3, 32, 1e-9), ("hg", -0.6, 64, 1e-9),  # truncation below the tolerance there
    ("hg", 0.6, 96, 1e-9), ("hg", 0.3, -1, 1e-6),   # the bake's own order choice
])
def test03_point_light_matches_phase_quadrature(phase, g, order, tol):
    s, D, c, V = random_point_rays(300, 2)
    a = _native.pegoraro10_airlight(s, D, c, V, phase, g, order)
    q = _native.airlight_quadrature(s, D, c, V, phase, g)
    rel = np.abs(a - q) / q
    print(f"{phase} g={g} order={order}: max rel {rel.max():.2e}")
    assert rel.max() < tol


def test04_hg_truncation_error_falls_with_order():
    """HG's Legendre series a_n = (2n+1) g^n truncated at N: the airlight error shrinks ~ g^N."""
    s, D, c, V = random_point_rays(200, 3)
    q = _native.airlight_quadrature(s, D, c, V, "hg", 0.6)
    errs = [np.max(np.abs(_native.pegoraro10_airlight(s, D, c, V, "hg", 0.6, n) - q) / q) for n in (8, 16, 32, 48)]
    print("HG 0.6 truncation error at order 8/16/32/48:", ", ".join(f"{e:.1e}" for e in errs))
    assert errs[0] > errs[1] > errs[2] > errs[3]
    assert errs[3] < 1e-7 and errs[0] > 1e-2
    assert _native.pegoraro_legendre("hg", 0.5, 3) == pytest.approx([1.0, 1.5, 1.25, 0.875])
    assert _native.pegoraro_legendre("rayleigh") == pytest.approx([1.0, 0.0, 0.5])


def test05_moments_match_quadrature():
    """G_m over both regimes of the recurrence (forward H <= 1.5, Olver above), up to m = 100."""
    from scipy import integrate
    for H, v0, v1 in ((1e-7, 0.3, 4.0), (0.5, 0.01, np.inf), (1.4, 2.0, 3.0), (1.0, 0.3, 4.0), (3.0, 0.3, 4.0),
                      (20.0, 0.001, 0.002), (100.0, 0.5, np.inf)):
        K = 100
        G = np.array(_native.pegoraro_moments(H, v0, v1, K))
        for m in (0, 1, 2, 7, 30, 100):
            def f(psi, part):
                v = math.tan(psi)
                val = np.exp(2j * m * psi - H * (v - v0))
                return val.real if part == 0 else val.imag
            lo, hi = math.atan(v0), (math.atan(v1) if np.isfinite(v1) else math.pi / 2)
            ref = complex(*(integrate.quad(f, lo, hi, args=(p,), epsabs=1e-15, epsrel=1e-12, limit=2000)[0]
                            for p in (0, 1)))
            err = abs(G[m] - ref) / max(abs(ref), 1e-3 * abs(G[0]))
            assert err < 1e-8, (H, v0, v1, m, G[m], ref)


SPOT_CASES = [(30, 0.0), (30, 0.15), (45, 0.15), (45, 1.0), (90, 0.001), (150, 0.15), (180, 0.0), (180, 1.0)]


def spot_rays(n, seed, pos, axis):
    rng = np.random.default_rng(seed)
    o = rng.normal(size=(n, 3)) * 4
    tgt = pos + axis / np.linalg.norm(axis) * rng.uniform(0, 8, (n, 1)) + rng.normal(size=(n, 3)) * 2
    d = tgt - o
    d /= np.linalg.norm(d, axis=1)[:, None]
    V = np.where(rng.uniform(size=n) < 0.3, np.inf, rng.uniform(0.5, 30, n))
    return o, d, V


@pytest.mark.parametrize("size_deg,blend", SPOT_CASES)
@pytest.mark.parametrize("phase,g", [("isotropic", 0.0), ("hg", 0.5)])
def test06_spot_matches_spot_quadrature(size_deg, blend, phase, g):
    pos, axis = np.array([1.0, 2.0, 3.0]), np.array([0.3, -1.0, 0.4])
    o, d, V = spot_rays(150, 4, pos, axis)
    args = (pos, axis, math.radians(size_deg), blend, 0.3, o, d, V)
    a = _native.pegoraro10_spot_airlight(*args, phase, g, 48 if phase == "hg" else -1)
    q = _native.spot_airlight_quadrature(*args, phase, g, 1e-10)
    lit = q > 1e-12 * q.max()
    rel = np.abs(a - q)[lit] / q[lit]
    print(f"spot {size_deg} deg blend {blend} {phase}: {lit.sum()} lit rays, max rel {rel.max():.2e}, "
          f"median {np.median(rel):.1e}")
    assert lit.sum() > 20
    assert rel.max() < 1e-5 and np.median(rel) < 1e-8
    assert np.all(a[~lit] <= 1e-10 * q.max())


def test07_polynomial_light_distribution():
    """I(c) = 1 + 2c + 3c^2 over a sub-segment vs scipy quadrature written out here."""
    from scipy import integrate
    pos, axis = np.array([0.0, 1.0, -2.0]), np.array([0.0, -0.6, 0.8])
    axis_u = axis / np.linalg.norm(axis)
    sig = 0.4
    rng = np.random.default_rng(5)
    for _ in range(20):
        o = rng.normal(size=3)
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        x0, x1 = rng.uniform(0, 1), rng.uniform(1.5, 12)
        got = _native.pegoraro10_ray_airlight([1.0, 2.0, 3.0], axis, pos, sig, o[None], d[None], x0, x1, "hg", 0.2, 40)[0]

        def f(x):
            p = o + x * d - pos
            r = np.linalg.norm(p)
            c = p @ axis_u / r
            mu = -(p @ d) / r
            ph = (1 - 0.04) / (4 * math.pi * (1 + 0.04 - 0.4 * mu) ** 1.5)
            return (1 + 2 * c + 3 * c * c) * ph * math.exp(-sig * (r + x)) / (r * r)
        a = -(o - pos) @ d
        pts = [a] if x0 < a < x1 else None
        ref = sig * integrate.quad(f, x0, x1, points=pts, epsabs=0, epsrel=1e-12, limit=500)[0]
        assert got == pytest.approx(ref, rel=1e-9)


def test08_bad_input_is_a_value_error():
    with pytest.raises(ValueError):
        _native.pegoraro10_airlight(-1.0, 1.0, 0.5, 1.0, "isotropic", 0.0)
    with pytest.raises(ValueError):
        _native.pegoraro10_airlight(1.0, 1.0, 0.5, float("nan"), "isotropic", 0.0)
    with pytest.raises(ValueError):
        _native.pegoraro10_airlight(1.0, 1.0, 0.5, 1.0, "hg", 1.0)
    with pytest.raises(ValueError):
        _native.pegoraro10_airlight(1.0, 1.0, 0.5, 1.0, "hg", 0.5, 500)
    with pytest.raises(ValueError):
        _native.pegoraro10_spot_airlight([0, 0, 0], [0, 0, 0], 1.0, 0.1, 0.1, [0, 0, 1], [[0, 0, -1]], [1.0])
    with pytest.raises(ValueError):
        _native.pegoraro10_spot_airlight([0, 0, 0], [0, 0, -1], 4.0, 0.1, 0.1, [0, 0, 1], [[0, 0, -1]], [1.0])


def floor_scene(width, height, **kw):
    """Bake arguments: a camera pitched down 10 degrees over the floor z = -10 filling the view."""
    v, t = plane_z(-10.0)
    return dict(width=width, height=height,
                cam_to_world=camera_matrix(rotation_x(math.radians(-10)), np.array([0, 0.5, 1.0])),
                projection=perspective(math.radians(60), width, height), vertices=v, triangles=t,
                albedo=(0.9, 0.8, 0.6), threads=2, aa_samples=1, **kw)


def test09_bake_spot_closed_form_vs_quadrature():
    """The bake's closed-form spots (sun05 isotropic; pegoraro10 with HG 0.5, order 30; biri06 with
    HG order 30 keeps the quadrature, so it must equal it) against the 'quadrature' model."""
    base = floor_scene(96, 64, light_positions=np.zeros((0, 3)), light_intensities=np.zeros((0, 3)), sigma_t=0.15,
                       spot_positions=np.array([[0.5, 3.0, -5.0], [-2.0, 1.0, -3.0]]),
                       spot_axes=np.array([[0.1, -1.0, -0.2], [0.6, -0.3, -1.0]]),
                       spot_intensities=np.array([[30.0, 20.0, 10.0], [5.0, 8.0, 12.0]]),
                       spot_size=np.radians([45.0, 120.0]), spot_blend=np.array([0.15, 1.0]))
    for phase, g, fast_model in (("isotropic", 0.0, "sun05"), ("hg", 0.5, "biri06"), ("hg", 0.5, "pegoraro10")):
        fast = _native.bake(model=fast_model, phase=phase, g=g, **base)["airlight"]
        ref = _native.bake(model="quadrature", phase=phase, g=g, **base)["airlight"]
        m = ref > 1e-3 * ref.max()
        rel = np.abs(fast - ref)[m] / ref[m]
        print(f"bake spots {phase} g={g} model {fast_model} vs quadrature: mean {rel.mean():.2e}, "
              f"p99 {np.percentile(rel, 99):.2e}, max {rel.max():.2e} over {m.sum()} pixel-channels")
        assert m.sum() > 1000
        assert rel.mean() < 1e-6 and np.percentile(rel, 99) < 2e-5


def test10_bake_pegoraro10_point_lights():
    """Model 'pegoraro10' for point lights with an anisotropic phase equals the quadrature model."""
    base = floor_scene(48, 32, light_positions=np.array([[1.0, 0.0, -4.0], [-3.0, 2.0, -8.0]]),
                       light_intensities=np.array([[2.0, 2.0, 3.0], [5.0, 1.0, 1.0]]), sigma_t=0.2, clip_start=0.2)
    for phase, g in (("hg", 0.6), ("hg", -0.3), ("rayleigh", 0.0), ("murky_mie", 0.0)):
        a = _native.bake(model="pegoraro10", phase=phase, g=g, **base)["airlight"]
        b = _native.bake(model="quadrature", phase=phase, g=g, **base)["airlight"]
        rel = np.abs(a - b) / b
        print(f"bake point lights {phase} g={g}: pegoraro10 vs quadrature max rel {rel.max():.2e}")
        assert rel.max() < 2e-6   # float32 passes
