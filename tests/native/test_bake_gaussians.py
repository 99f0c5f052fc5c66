"""Bakes with Gaussian fog (Fogshop) through the binding: the Transmittance pass against
exp(-optical depth) summed here in numpy/scipy from eq. 31 (erf, independent of the C++),
the Airlight pass against `RbfMedium.airlight(model="quadrature")` from the near point
(the Fogshop approximation's thin-fog bound: mean 1 %, p99 3 %, airlight_test.cpp),
the "quadrature" model to 1e-6, no-Gaussians bit-identical, and bad rbf_* input."""
import math

import numpy as np
import pytest

import _native
from reference_util import gaussian_depths
from scene_fog_objects import ALBEDO, CAM_POS, CLIP, FOV, H, INTENSITY, LIGHTS, SIGMA_T, W, bake
from scene_util import few_gaussians, pixel_dirs_camera


def optical_depth(b, a, c, o, d, t0, t1):
    """sigma_t (t1 - t0) + sum_i T_i along o + t d (eq. 31)."""
    if math.isinf(t1):
        return math.inf
    return SIGMA_T * (t1 - t0) + gaussian_depths(b, a, c, o, d, t0, t1).sum()


def test01_transmittance_and_airlight_match_references():
    b, a, c = few_gaussians()
    out = bake(rbf_centres=b, rbf_scales=a, rbf_amplitudes=c)
    quad_model = bake(rbf_centres=b, rbf_scales=a, rbf_amplitudes=c, model="quadrature")
    medium = _native.RbfMedium(b, a, c, beta0=SIGMA_T)
    dirs = pixel_dirs_camera(FOV, W, H)
    errs, hits = [], 0
    for j in range(H):
        for i in range(W):
            d = dirs[j, i]
            t0 = CLIP / -d[2]
            depth = float(out["depth"][j, i])
            hits += not math.isinf(depth)
            T = optical_depth(b, a, c, CAM_POS, d, t0, depth)
            np.testing.assert_allclose(out["transmittance"][j, i], math.exp(-T), atol=1e-6)
            if (i + j) % 3:
                continue  # the quadrature reference is slow: a third of the pixels
            o = CAM_POS + t0 * d
            per_light = medium.airlight(LIGHTS, o, d[None, :], np.array([depth - t0]), model="quadrature")[0]
            ref = (per_light[:, None] * INTENSITY).sum(0) * np.array(ALBEDO)
            errs.extend(np.abs(out["airlight"][j, i] / ref - 1))
            np.testing.assert_allclose(quad_model["airlight"][j, i], ref, rtol=1e-6)
    assert 100 < hits < W * H - 100
    errs = np.sort(errs)
    mean, p99 = errs.mean(), errs[int(0.99 * len(errs))]
    print(f"fogshop bake vs quadrature: mean {mean:.4f} p99 {p99:.4f} max {errs[-1]:.4f}")
    assert mean < 0.01 and p99 < 0.03


def test02_gaussians_change_the_passes_and_none_is_bit_identical():
    plain = bake()
    b, a, c = few_gaussians(scale=1.0)
    fog = bake(rbf_centres=b, rbf_scales=a, rbf_amplitudes=c)
    assert np.max(plain["transmittance"] - fog["transmittance"]) > 0.05
    assert np.all(fog["transmittance"] <= plain["transmittance"] + 1e-7)
    empty = bake(rbf_centres=np.zeros((0, 3)), rbf_scales=np.zeros(0), rbf_amplitudes=np.zeros(0))
    for key in ("airlight", "transmittance", "depth"):
        assert np.array_equal(plain[key], empty[key])
        assert np.array_equal(plain[key], bake(rbf_centres=None)[key])


def test03_progress_and_cancel_with_gaussians():
    b, a, c = few_gaussians()
    seen = []
    bake(rbf_centres=b, rbf_scales=a, rbf_amplitudes=c, progress=lambda f: seen.append(f))
    assert seen[-1] == 1.0 and seen == sorted(seen)
    with pytest.raises(_native.BakeCancelled):
        bake(rbf_centres=b, rbf_scales=a, rbf_amplitudes=c, progress=lambda f: f < 0.5)


def test03b_stats_phases_are_disjoint_parts_of_the_bake():
    """stats' phase times: the raycast, the fog model's set-up and the airlight pass are
    successive parts of one bake, so their sum stays within the wall time around the call;
    binning and the edge pass lie inside the airlight pass (binning on the calling thread's
    clock; the edge pass summed over 2 threads: at most twice it). 3000 Gaussians, so that
    the set-up (their medium and per-light depths) takes a measurable time."""
    import time
    rng = np.random.default_rng(3)
    n = 3000
    b = np.column_stack([40 * rng.random(n) - 20, 6 * rng.random(n) - 3, -(10 + 40 * rng.random(n))])
    a = 1.0 / (1.0 + 2.0 * rng.random(n))
    c = 0.01 + 0.04 * rng.random(n)
    for resolution in ("full", "quarter"):
        t0 = time.perf_counter()
        st = bake(rbf_centres=b, rbf_scales=a, rbf_amplitudes=c, gaussian_resolution=resolution)["stats"]
        wall = time.perf_counter() - t0
        assert st["seconds_fog_setup"] > 0.0 and st["seconds_raycast"] > 0.0 and st["seconds_bin"] > 0.0
        assert st["seconds_raycast"] + st["seconds_fog_setup"] + st["seconds_airlight"] <= wall
        assert st["seconds_bin"] <= st["seconds_airlight"]
        assert st["seconds_edges"] <= 2.0 * st["seconds_airlight"]
    # Without fog objects nothing is binned.
    st = bake()["stats"]
    assert st["seconds_bin"] == 0.0 and st["seconds_fog_setup"] >= 0.0


def test04_bad_input():
    b, a, c = few_gaussians()
    bad = [
        dict(rbf_centres=b, rbf_scales=a),                                    # not all three
        dict(rbf_centres=b[:, :2], rbf_scales=a, rbf_amplitudes=c),           # shape
        dict(rbf_centres=b, rbf_scales=a[:-1], rbf_amplitudes=c),             # length
        dict(rbf_centres=b, rbf_scales=a, rbf_amplitudes=c[:-1]),
        dict(rbf_centres=np.where(np.arange(12)[:, None] == 3, np.nan, b), rbf_scales=a, rbf_amplitudes=c),
        dict(rbf_centres=b, rbf_scales=np.where(np.arange(12) == 2, 0.0, a), rbf_amplitudes=c),
        dict(rbf_centres=b, rbf_scales=np.where(np.arange(12) == 2, -1.0, a), rbf_amplitudes=c),
        dict(rbf_centres=b, rbf_scales=a, rbf_amplitudes=np.where(np.arange(12) == 1, np.nan, c)),
        dict(rbf_centres=b, rbf_scales=a, rbf_amplitudes=-c),
    ]
    for kw in bad:
        with pytest.raises(ValueError, match="rbf_"):
            bake(**kw)
    # (anisotropic phases, biri06 / pegoraro10, suns and spots with Gaussians: test_bake_gaussians_lights.py)
    with pytest.raises(ValueError, match="does not take fog objects"):
        bake(rbf_centres=b, rbf_scales=a, rbf_amplitudes=c, model="hoffman02", light_positions=np.zeros((0, 3)),
             light_intensities=np.zeros((0, 3)))
