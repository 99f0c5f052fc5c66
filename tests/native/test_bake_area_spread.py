"""Area lights with a Spread below 180 degrees: bakes of their spot samples (spot_spread) per
pixel against an independent scipy quadrature of the single-scattering integral with Cycles
3.4's soft-box profile written out here (kernel/light/area.h: radiance times
max(1 - tan(theta) / tan(h), 0) / (1 - h / tan(h)), h = spread / 2, on top of the Lambert
cos(theta)), its kinks (the cone at h, the axis where the ray crosses it) bracketed
numerically; the profile's power; every model, a phase, the near plane, Gaussian fog, and
the argument checks."""
import math

import numpy as np
import pytest
from scipy import integrate, optimize

import _native
from reference_util import hg
from scene_util import pixel_dirs_camera, rotation_x
# The spot tests' camera, floor and fog (scene() builds the bake's arguments).
from test_bake_spot_lights import ALBEDO, CAM_POS, FOV, H, PLANE_Z, SIGMA_T, TILT, W, scene

# Two samples of area lights aimed down into the view, Spread 40 and 100 degrees.
SPOT_POS = np.array([[0.5, 3.0, -5.0], [-2.0, 2.0, -3.0]])
SPOT_AXIS = np.array([[0.1, -1.0, -0.2], [0.6, -0.8, -1.0]])
SPOT_I = np.array([[30.0, 20.0, 10.0], [5.0, 8.0, 12.0]])
SPREAD = np.array([math.radians(40.0), math.radians(100.0)])


def cycles_profile(axis, spread, u):
    """Cycles' area-light factor toward the unit direction u: cos(theta) times the soft box."""
    c = float(axis @ u)
    if c <= 0.0:
        return 0.0
    if spread >= math.pi:
        return c
    h = spread / 2
    tan_t = math.sqrt(max(0.0, 1.0 - c * c)) / c
    return c * max(1.0 - tan_t / math.tan(h), 0.0) / (1.0 - h / math.tan(h))


def reference(o, d, t0, t1, g=0.0, spreads=SPREAD):
    """sigma_s sum_samples int_t0^t1 I(theta) p e^{-sigma_t (|x - s| + t - t0)} / |x - s|^2 dt."""
    total = np.zeros(3)
    end = t1 if math.isfinite(t1) else t0 + 400.0   # e^{-0.15 * 400}: negligible beyond
    for s, axis, I0, spread in zip(SPOT_POS, SPOT_AXIS, SPOT_I, spreads):
        axis = axis / np.linalg.norm(axis)
        ch = math.cos(spread / 2)

        def cos_axis(t):
            w = o + t * d - s
            return float(axis @ w) / math.sqrt(w @ w)

        def f(t):
            w = o + t * d - s
            r = math.sqrt(w @ w)
            return cycles_profile(axis, spread, w / r) * hg(-(w @ d) / r, g) * \
                math.exp(-SIGMA_T * (r + t - t0)) / (r * r)
        ts = t0 + (end - t0) * np.linspace(0.0, 1.0, 2401) ** 2
        v = np.array([cos_axis(t) for t in ts])
        pts = {t0, end}
        for i in range(len(ts) - 1):   # the cone's edge
            if (v[i] - ch) * (v[i + 1] - ch) < 0:
                pts.add(optimize.brentq(lambda t: cos_axis(t) - ch, ts[i], ts[i + 1], xtol=1e-13))
        k = int(np.argmax(v))           # the axis (the profile's kink): the largest cos(theta)
        lo, hi = ts[max(k - 1, 0)], ts[min(k + 1, len(ts) - 1)]
        if hi > lo:
            pts.add(optimize.minimize_scalar(lambda t: -cos_axis(t), bounds=(lo, hi), method="bounded",
                                             options=dict(xatol=1e-12)).x)
        a = float((s - o) @ d)
        if t0 < a < end:
            pts.add(a)
        pts = sorted(p for p in pts if t0 <= p <= end)
        val = sum(integrate.quad(f, lo, hi, epsabs=0, epsrel=1e-10, limit=400)[0]
                  for lo, hi in zip(pts, pts[1:]) if hi > lo)
        total += SIGMA_T * np.array(ALBEDO) * I0 * val
    return total


def samples(spreads=SPREAD):
    return dict(spot_positions=SPOT_POS, spot_axes=SPOT_AXIS, spot_intensities=SPOT_I,
                spot_size=np.full(2, math.pi), spot_blend=np.zeros(2), spot_spread=np.asarray(spreads))


def check(out, near=0.0, g=0.0, rtol=1e-5, spreads=SPREAD, min_checked=20):
    dirs = pixel_dirs_camera(FOV, W, H) @ rotation_x(TILT).T
    view = rotation_x(TILT) @ np.array([0.0, 0.0, -1.0])
    A = out["airlight"]
    errs, checked = [], 0
    for j in range(0, H, 3):
        for i in range(0, W, 2):
            d = dirs[j, i]
            t1 = (PLANE_Z - CAM_POS[2]) / d[2] if d[2] < 0 else math.inf
            t0 = near / float(d @ view)
            ref = reference(CAM_POS, d, t0, t1, g, spreads)
            scale = max(ref.max(), 1e-6)
            errs.append(np.abs(A[j, i] - ref).max() / scale)
            checked += ref.max() > 1e-4
    assert checked > min_checked, "the frame should see the samples' beams"
    print(f"checked {checked}, max relative error {max(errs):.2e}")
    assert max(errs) < rtol, f"max relative error {max(errs):.2e}"


@pytest.mark.parametrize("spread_deg", [1.0, 10.0, 60.0, 120.0, 179.0, 180.0])
def test_profile_keeps_the_power(spread_deg):
    """Cycles normalises the soft box to the Lambert emitter's power: int I dOmega = pi; the
    native profile (spot_cone's constants) is Cycles' factor written out above."""
    spread = math.radians(spread_deg)
    cos_half, smooth, a, b = _native.spot_cone(math.pi, 0.0, spread)
    h = spread / 2
    assert smooth == 0.0 and cos_half == pytest.approx(math.cos(h), abs=1e-15)
    prof = lambda t: max(0.0, a * math.cos(t) - b * math.sin(t)) if t < h else 0.0  # noqa: E731
    power = 2 * math.pi * integrate.quad(lambda t: prof(t) * math.sin(t), 0, h, epsabs=0, epsrel=1e-12)[0]
    assert power == pytest.approx(math.pi, rel=1e-9)
    axis = np.array([0.0, 0.0, 1.0])
    for t in np.linspace(0.0, 0.999 * h, 9):
        u = np.array([math.sin(t), 0.0, math.cos(t)])
        assert prof(t) == pytest.approx(cycles_profile(axis, spread, u), rel=1e-9, abs=1e-12 * a)


@pytest.mark.parametrize("model", ["sun05", "pegoraro10", "biri06", "quadrature"])
def test_spread_bake_matches_reference(model):
    check(_native.bake(**scene(model=model, **samples())))


def test_spread_bake_narrow_and_near_plane():
    spreads = np.radians([3.0, 25.0])
    check(_native.bake(**scene(clip_start=1.5, **samples(spreads))), near=1.5, spreads=spreads, min_checked=10)


@pytest.mark.parametrize("model", ["pegoraro10", "quadrature"])
def test_spread_bake_hg_phase(model):
    check(_native.bake(**scene(phase="hg", g=0.5, model=model, **samples())), g=0.5)


def test_full_spread_is_the_plain_sample():
    """Spread 180 degrees is Cycles' default: the same bits as no spot_spread."""
    a = _native.bake(**scene(**samples(np.full(2, math.pi))))
    b = _native.bake(**scene(**{k: v for k, v in samples().items() if k != "spot_spread"}))
    np.testing.assert_array_equal(a["airlight"], b["airlight"])


def test_spread_in_gaussian_fog():
    """Fog objects lit by Spread samples: Automatic's refinement against the bake's own exact
    Gaussian quadrature (model quadrature) within the accuracy asked."""
    gauss = dict(rbf_centres=np.array([[0.3, 1.5, -4.5], [-1.5, 0.5, -3.5]]), rbf_scales=np.array([0.8, 0.6]),
                 rbf_amplitudes=np.array([0.6, 0.9]))
    exact = _native.bake(**scene(model="quadrature", **gauss, **samples()))["airlight"].astype(np.float64)
    auto = _native.bake(**scene(model="biri06", gaussian_accuracy=0.01, **gauss, **samples()))["airlight"]
    lit = exact.max(axis=-1) > 1e-3 * exact.max()
    rel = np.abs(auto - exact).max(axis=-1)[lit] / exact.max(axis=-1)[lit]
    print(f"mean {rel.mean():.2e}, max {rel.max():.2e}")
    assert rel.mean() < 0.01, rel.mean()


def test_spread_argument_errors():
    bad = samples()
    bad["spot_spread"] = np.array([0.5])
    with pytest.raises(ValueError, match="spot_spread"):
        _native.bake(**scene(**bad))
    bad = samples()
    bad["spot_spread"] = np.array([math.radians(0.5), 1.0])
    with pytest.raises(ValueError, match="spread"):
        _native.bake(**scene(**bad))
    bad = samples()
    bad["spot_spread"] = np.array([np.nan, 1.0])
    with pytest.raises(ValueError, match="spread"):
        _native.bake(**scene(**bad))
    bad = samples()
    bad["spot_size"] = np.array([1.0, math.pi])
    with pytest.raises(ValueError, match="spot_size pi"):
        _native.bake(**scene(**bad))
    with pytest.raises(ValueError, match="spot_spread needs"):
        _native.bake(**scene(spot_spread=np.array([1.0])))
    with pytest.raises(ValueError, match="180 deg cone"):
        _native.spot_cone(1.0, 0.0, 1.0)


def test_spread_surface_pass_runs_and_is_bounded():
    """The surface glow of Spread samples (SpotGlowModel, its table keyed by the Spread too):
    finite, >= 0, and below the same samples' glow at 180 degrees scaled by the profile's peak."""
    wide = _native.bake(**scene(surface=True, **samples(np.full(2, math.pi))))
    narrow = _native.bake(**scene(surface=True, **samples()))
    glow_n, glow_w = narrow["surface_glow"], wide["surface_glow"]
    assert np.isfinite(glow_n).all() and (glow_n >= 0).all()
    peak = max(_native.spot_cone(math.pi, 0.0, s)[2] for s in SPREAD)
    assert (glow_n <= peak * glow_w + 1e-6).all()
    assert not np.array_equal(glow_n, glow_w)
