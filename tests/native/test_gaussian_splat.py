"""Gaussian fog through the splat path of the bake (splat.h), via the binding:
`rbf_preview_factors` against optical depths summed here in numpy/scipy (eq. 31, no
culling), per-Gaussian colour (`rbf_albedo`) and Fogshop noise (`noise_*`): off is
bit-identical, on changes the image deterministically and within the line-integral bound;
bad input raises ValueError."""
import math

import numpy as np
import pytest

import _native
from reference_util import gaussian_depths
from scene_util import camera_matrix, perspective, plane_y, rotation_x

W, H = 40, 24
FOV = math.radians(60.0)
SIGMA_T = 0.01
LIGHTS = np.array([[4.0, 10.0, -12.0], [-6.0, 3.0, -25.0]])
INTENSITY = np.array([[100.0, 80.0, 60.0], [30.0, 30.0, 40.0]])


def cloud(n=20, seed=3):
    rng = np.random.default_rng(seed)
    b = np.column_stack([12 * rng.random(n) - 6, 4 * rng.random(n) - 2, -(8 + 20 * rng.random(n))])
    a = 1.0 / (0.5 + 1.5 * rng.random(n))
    c = 0.05 + 0.2 * rng.random(n)
    return b, a, c


def segment_depth(b, a, c, p, q):
    """(beta0 |q - p| + sum_i T_i(p, q), the T_i): eq. 31 with erf, every Gaussian (no culling)."""
    L = np.linalg.norm(q - p)
    Ti = gaussian_depths(b, a, c, p, (q - p) / L, 0.0, L)
    return SIGMA_T * L + Ti.sum(), Ti


def bake(**kw):
    vertices, triangles = plane_y(-3.0, x=(-300.0, 300.0), z=(1.0, -200.0))
    args = dict(width=W, height=H, cam_to_world=camera_matrix(rotation_x(0.0), np.zeros(3)),
                projection=perspective(FOV, W, H), vertices=vertices, triangles=triangles,
                light_positions=LIGHTS, light_intensities=INTENSITY, sigma_t=SIGMA_T, albedo=(0.9, 0.8, 0.7),
                clip_start=0.1, threads=2, aa_samples=1)
    args.update(kw)
    return _native.bake(**args)


def test01_preview_factors_vs_numpy():
    b, a, c = cloud()
    eye = np.array([0.5, 0.2, 1.0])
    f = _native.rbf_preview_factors(b, a, c, SIGMA_T, eye, LIGHTS, threads=2)
    n, m = len(a), len(LIGHTS)
    assert f["T_vb"].shape == (n,) and f["T_sb"].shape == (m, n) and f["C_sv"].shape == (m,)
    assert f["own_vb"].shape == (n,) and f["own_sb"].shape == (m, n) and f["D_sv"].shape == (m,)
    assert f["cull_radius"].shape == (n,)
    for i in range(n):
        T, Ti = segment_depth(b, a, c, eye, b[i])
        np.testing.assert_allclose(f["T_vb"][i], T, rtol=2e-5, atol=1e-6)
        np.testing.assert_allclose(f["own_vb"][i], Ti[i], rtol=1e-9)
        for l in range(m):
            T, Ti = segment_depth(b, a, c, LIGHTS[l], b[i])
            np.testing.assert_allclose(f["T_sb"][l, i], T, rtol=2e-5, atol=1e-6)
            np.testing.assert_allclose(f["own_sb"][l, i], Ti[i], rtol=1e-9)
    for l in range(m):
        T, _ = segment_depth(b, a, c, LIGHTS[l], eye)
        D = np.linalg.norm(LIGHTS[l] - eye)
        np.testing.assert_allclose(f["D_sv"][l], D, rtol=1e-12)
        np.testing.assert_allclose(f["C_sv"][l], math.exp(-(T - SIGMA_T * D)), rtol=1e-6)
    # No lights: the eye's factors only.
    f0 = _native.rbf_preview_factors(b, a, c, SIGMA_T, eye, np.zeros((0, 3)))
    assert f0["T_sb"].shape == (0, n)
    np.testing.assert_allclose(f0["T_vb"], f["T_vb"], rtol=1e-12)


def test02_preview_factors_bad_input():
    b, a, c = cloud(4)
    with pytest.raises(ValueError):
        _native.rbf_preview_factors(b, -a, c, SIGMA_T, np.zeros(3), LIGHTS)
    with pytest.raises(ValueError):
        _native.rbf_preview_factors(b, a, c, SIGMA_T, np.array([0.0, np.nan, 0.0]), LIGHTS)
    with pytest.raises(ValueError):
        _native.rbf_preview_factors(b, a, c, -1.0, np.zeros(3), LIGHTS)
    with pytest.raises(ValueError):
        _native.rbf_preview_factors(b, a, c, SIGMA_T, np.zeros(3), np.array([[0.0, 1.0, np.inf]]))


def test03_per_gaussian_colour():
    # Two Gaussians side by side, red-ish and blue-ish, no background, one white light.
    b = np.array([[-3.0, 0.0, -10.0], [3.0, 0.0, -10.0]])
    a = np.array([2.0, 2.0])
    c = np.array([0.5, 0.5])
    colours = np.array([[1.0, 0.2, 0.0], [0.0, 0.3, 1.0]])
    kw = dict(rbf_centres=b, rbf_scales=a, rbf_amplitudes=c, sigma_t=0.0, albedo=(1.0, 1.0, 1.0),
              light_positions=np.array([[0.0, 4.0, -10.0]]), light_intensities=np.array([[10.0, 10.0, 10.0]]))
    out = bake(**kw, rbf_albedo=colours)
    A = out["airlight"].astype(np.float64)
    # Pixel columns looking at x = -3 and x = +3 at depth 10 (60 degree horizontal view).
    t = math.tan(FOV / 2)
    col = lambda x: int(((x / 10.0) / t * 0.5 + 0.5) * W)
    left, right = A[H // 2, col(-3.0)], A[H // 2, col(3.0)]
    assert left[0] > 0 and right[2] > 0
    np.testing.assert_allclose(left[1] / left[0], 0.2, rtol=1e-3)
    assert left[2] < 1e-3 * left[0]
    np.testing.assert_allclose(right[1] / right[2], 0.3, rtol=1e-3)
    assert right[0] < 1e-3 * right[2]
    # A black background medium still carries coloured fog objects (no homogeneous term here).
    black = bake(**{**kw, "albedo": (0.0, 0.0, 0.0)}, rbf_albedo=colours)
    assert np.array_equal(black["airlight"], out["airlight"])
    # Every Gaussian with the medium's colour: the same image as without rbf_albedo.
    grey = bake(**kw, rbf_albedo=np.ones((2, 3)))
    plain = bake(**kw)
    assert np.array_equal(grey["airlight"], plain["airlight"])
    # Colour scales the airlight linearly (channel by channel).
    half = bake(**kw, rbf_albedo=0.5 * np.ones((2, 3)))
    np.testing.assert_allclose(half["airlight"], 0.5 * plain["airlight"], rtol=1e-6, atol=1e-12)
    with pytest.raises(ValueError):
        bake(**kw, rbf_albedo=np.ones((3, 3)))
    with pytest.raises(ValueError):
        bake(**kw, rbf_albedo=-np.ones((2, 3)))
    with pytest.raises(ValueError):
        bake(**kw, rbf_albedo=colours, model="quadrature")


def test04_noise_off_is_identical_on_is_bounded():
    b, a, c = cloud()
    kw = dict(rbf_centres=b, rbf_scales=a, rbf_amplitudes=c)
    base = bake(**kw)
    off = bake(**kw, noise_amplitude=0.0, noise_scale=0.3, noise_offset=(1.0, 2.0, 3.0))
    assert np.array_equal(base["airlight"], off["airlight"])
    assert np.array_equal(base["transmittance"], off["transmittance"])
    on = bake(**kw, noise_amplitude=0.5, noise_scale=0.8)
    again = bake(**kw, noise_amplitude=0.5, noise_scale=0.8)
    assert np.array_equal(on["airlight"], again["airlight"])  # deterministic
    moved = bake(**kw, noise_amplitude=0.5, noise_scale=0.8, noise_offset=(0.5, 0.0, 0.0))
    np.seterr(divide="ignore", invalid="ignore")  # log(0) on misses, masked below
    depth = base["depth"].astype(np.float64)
    hit = np.isfinite(depth)
    T0 = -np.log(base["transmittance"][..., 0].astype(np.float64))
    T1 = -np.log(on["transmittance"][..., 0].astype(np.float64))
    T2 = -np.log(moved["transmittance"][..., 0].astype(np.float64))
    assert np.mean(np.abs(T1 - T0)[hit]) > 1e-3
    assert np.mean(np.abs(T2 - T1)[hit]) > 1e-4  # the offset moves the pattern
    # Each Gaussian's line integral stays within [0, c sqrt(pi) / a] (a direction change
    # cannot exceed the whole Gaussian's integral): the bound on the noisy optical depth.
    t0 = 0.1  # clip_start along the view axis; the background is sigma_t over [t0/cos, depth]
    bound = np.sum(c * math.sqrt(math.pi) / a)
    assert np.all(T1[hit] <= T0[hit] + bound + 1e-5)
    assert np.all(np.isfinite(on["airlight"])) and np.all(on["airlight"] >= 0)
    rel = np.abs(on["airlight"] - base["airlight"]) / np.maximum(base["airlight"], 1e-30)
    assert 1e-3 < np.mean(rel) < 1.0
    # Edge supersampling runs the per-ray twin of the splat with noise too.
    aa = bake(**kw, noise_amplitude=0.5, noise_scale=0.8, aa_samples=4)
    assert aa["stats"]["supersampled_pixels"] > 0
    assert np.all(np.isfinite(aa["airlight"]))
    with pytest.raises(ValueError):
        bake(**kw, noise_amplitude=-0.1)
    with pytest.raises(ValueError):
        bake(**kw, noise_amplitude=0.5, noise_scale=0.0)
    with pytest.raises(ValueError):
        bake(**kw, noise_amplitude=0.5, noise_offset=(0.0, np.nan, 0.0))
    with pytest.raises(ValueError):
        bake(**kw, noise_amplitude=0.5, model="quadrature")


def test05_preview_factors_incremental_equals_full():
    b, a, c = cloud(40, seed=8)
    eye = np.array([0.3, 0.1, 0.5])
    old = _native.rbf_preview_factors(b[:30], a[:30], c[:30], SIGMA_T, eye, LIGHTS)
    full = _native.rbf_preview_factors(b, a, c, SIGMA_T, eye, LIGHTS)
    inc = _native.rbf_preview_factors(b, a, c, SIGMA_T, eye, LIGHTS, previous=old, first_new=30)
    for key in ("T_vb", "own_vb", "T_sb", "own_sb", "C_sv", "D_sv", "cull_radius"):
        np.testing.assert_allclose(inc[key], full[key], rtol=2e-5, atol=1e-7, err_msg=key)
    with pytest.raises(ValueError):
        _native.rbf_preview_factors(b, a, c, SIGMA_T, eye, LIGHTS, previous=old, first_new=29)
    with pytest.raises(ValueError):
        _native.rbf_preview_factors(b, a, c, SIGMA_T, eye, LIGHTS[:1], previous=old, first_new=30)


def test08_incremental_stroke_in_a_spread_cloud():
    """A stroke of 40 small Gaussians added to 400 spread over a large volume: most new
    Gaussians' cull spheres miss most old segments (the incremental call skips those, as
    the full call's culling does). Incremental = from scratch to float rounding, and both
    within the culling bound (cull_eps per skipped Gaussian) of numpy's unculled sum."""
    rng = np.random.default_rng(21)

    def spread(n):
        b = np.column_stack([rng.uniform(-40, 40, n), rng.uniform(-3, 6, n), rng.uniform(-90, -8, n)])
        return b, 1.0 / rng.uniform(0.5, 1.5, n), rng.uniform(0.05, 0.3, n)

    (b0, a0, c0), (b1, a1, c1) = spread(400), spread(40)
    b, a, c = np.concatenate([b0, b1]), np.concatenate([a0, a1]), np.concatenate([c0, c1])
    eye = np.array([0.0, 1.0, 0.0])
    old = _native.rbf_preview_factors(b0, a0, c0, SIGMA_T, eye, LIGHTS)
    full = _native.rbf_preview_factors(b, a, c, SIGMA_T, eye, LIGHTS)
    inc = _native.rbf_preview_factors(b, a, c, SIGMA_T, eye, LIGHTS, previous=old, first_new=400)
    for key in ("T_vb", "own_vb", "T_sb", "own_sb", "C_sv", "D_sv", "cull_radius"):
        np.testing.assert_allclose(inc[key], full[key], rtol=2e-5, atol=1e-7, err_msg=key)
    bound = 1e-7 * len(a) + 2e-5
    for i in range(0, 440, 7):
        T, _ = segment_depth(b, a, c, eye, b[i])
        assert abs(inc["T_vb"][i] - T) <= bound * max(1.0, T)
        for l in range(len(LIGHTS)):
            T, _ = segment_depth(b, a, c, LIGHTS[l], b[i])
            assert abs(inc["T_sb"][l, i] - T) <= bound * max(1.0, T)


def test09_preview_factors_many_gaussians_lights_inside():
    """6000 small Gaussians with the lights and the eye inside the cloud: enough of both
    targets and candidates that rbf_preview_factors bins the Gaussians by direction around
    each source (centre_depths.h, gaussian_depths_to_centres); a stroke of 300 more updates the old
    Gaussians per new candidate. Against numpy's unculled sums (eq. 31 with scipy's erf) on
    a sample of centres, within float rounding and the culling bound; incremental equals
    the call from scratch."""
    rng = np.random.default_rng(5)

    def cloud_box(n):
        b = np.column_stack([rng.uniform(-15, 15, n), rng.uniform(-3, 9, n), rng.uniform(-40, 2, n)])
        return b, 1.0 / rng.uniform(0.3, 1.0, n), rng.uniform(0.05, 0.3, n)

    (b0, a0, c0), (b1, a1, c1) = cloud_box(6000), cloud_box(300)
    b, a, c = np.concatenate([b0, b1]), np.concatenate([a0, a1]), np.concatenate([c0, c1])
    eye = np.array([0.5, 1.0, -3.0])
    lights = np.array([[4.0, 2.0, -12.0], [-6.0, 3.0, -25.0], [20.0, 1.0, -20.0]])  # two inside, one outside
    full = _native.rbf_preview_factors(b, a, c, SIGMA_T, eye, lights, threads=2)
    old = _native.rbf_preview_factors(b0, a0, c0, SIGMA_T, eye, lights, threads=2)
    inc = _native.rbf_preview_factors(b, a, c, SIGMA_T, eye, lights, threads=2, previous=old, first_new=6000)
    bound = 1e-7 * len(a)
    worst, biggest = 0.0, 0.0
    for i in list(range(0, 6300, 97)) + [6001, 6299]:
        for l, p in enumerate([eye] + list(lights)):
            T, Ti = segment_depth(b, a, c, p, b[i])
            for f in (full, inc):
                got = f["T_vb"][i] if l == 0 else f["T_sb"][l - 1, i]
                own = f["own_vb"][i] if l == 0 else f["own_sb"][l - 1, i]
                worst = max(worst, abs(got - T) / (2e-5 * T + bound))
                np.testing.assert_allclose(own, Ti[i], rtol=1e-9)
            biggest = max(biggest, T)
    assert biggest > 2.0  # the Gaussians matter
    assert worst <= 1.0, worst
    for key in ("T_vb", "own_vb", "T_sb", "own_sb", "C_sv", "D_sv", "cull_radius"):
        np.testing.assert_allclose(inc[key], full[key], rtol=2e-5, atol=1e-7, err_msg=key)


def test10_preview_factors_eye_only_equals_full():
    """The view-change form (eye_only=True, the viewport orbiting): with the light rows of
    a call at another eye, the eye row, C_sv and D_sv at the new eye equal the full call's
    (the same star of segments; a light row that depended on the eye would differ: the old
    eye's rows are given) and numpy's unculled sums; the light rows are the previous ones.
    Both small (one thread, per-target sums) and 6000 Gaussians (threaded, binned)."""
    rng = np.random.default_rng(11)
    for n, eyes in ((40, ([0.3, 0.1, 0.5], [5.0, 2.0, -3.0])), (6000, ([0.5, 1.0, -3.0], [-8.0, 4.0, -30.0]))):
        b = np.column_stack([rng.uniform(-15, 15, n), rng.uniform(-3, 9, n), rng.uniform(-40, 2, n)])
        a, c = 1.0 / rng.uniform(0.3, 1.0, n), rng.uniform(0.05, 0.3, n)
        eye0, eye1 = np.array(eyes[0]), np.array(eyes[1])
        old = _native.rbf_preview_factors(b, a, c, SIGMA_T, eye0, LIGHTS, threads=2)
        full = _native.rbf_preview_factors(b, a, c, SIGMA_T, eye1, LIGHTS, threads=2)
        moved = _native.rbf_preview_factors(b, a, c, SIGMA_T, eye1, LIGHTS, threads=2, previous=old, eye_only=True)
        for key in ("T_vb", "own_vb", "T_sb", "own_sb", "C_sv", "D_sv", "cull_radius"):
            np.testing.assert_allclose(moved[key], full[key], rtol=1e-12, atol=0.0, err_msg=key)
        # The eye row really moved (the test would catch a copied eye row).
        assert np.max(np.abs(old["T_vb"] - full["T_vb"])) > 0.1
        bound = 1e-7 * n
        for i in range(0, n, max(1, n // 40)):
            T, Ti = segment_depth(b, a, c, eye1, b[i])
            assert abs(moved["T_vb"][i] - T) <= 2e-5 * T + bound
            np.testing.assert_allclose(moved["own_vb"][i], Ti[i], rtol=1e-9)
        for l in range(len(LIGHTS)):
            T, _ = segment_depth(b, a, c, LIGHTS[l], eye1)
            D = np.linalg.norm(LIGHTS[l] - eye1)
            np.testing.assert_allclose(moved["C_sv"][l], math.exp(-(T - SIGMA_T * D)), rtol=1e-6 + bound)
    # The previous factors must hold all the Gaussians' light rows for the same lights.
    with pytest.raises(ValueError):
        _native.rbf_preview_factors(b, a, c, SIGMA_T, eye1, LIGHTS, eye_only=True)
    with pytest.raises(ValueError):
        _native.rbf_preview_factors(b, a, c, SIGMA_T, eye1, LIGHTS[:1], previous=old, eye_only=True)
    with pytest.raises(ValueError):
        _native.rbf_preview_factors(b[:-1], a[:-1], c[:-1], SIGMA_T, eye1, LIGHTS, previous=old, eye_only=True)
    with pytest.raises(ValueError):
        _native.rbf_preview_factors(b, a, c, SIGMA_T, np.array([np.nan, 0.0, 0.0]), LIGHTS, previous=old,
                                    eye_only=True)
