"""Whole-image bakes of tiny scenes against analytic depths and per-ray model values."""
import math

import numpy as np
import pytest

import _native
from scene_floor import CAM_POS, FOV, H, PLANE_Z, SIGMA_T, W, analytic_depth, bake, world_dirs
from scene_util import camera_matrix, orthographic, pixel_dirs_camera, plane_z


def test01_shapes_and_types():
    out = bake()
    assert out["airlight"].shape == (H, W, 3) and out["airlight"].dtype == np.float32
    assert out["transmittance"].shape == (H, W, 3) and out["transmittance"].dtype == np.float32
    assert out["depth"].shape == (H, W) and out["depth"].dtype == np.float32
    stats = out["stats"]
    assert stats["samples"] >= W * H
    assert stats["seconds_raycast"] >= 0 and stats["seconds_airlight"] >= 0


def test02_depth_is_ray_plane_distance():
    out = bake()
    np.testing.assert_allclose(out["depth"], analytic_depth(), rtol=1e-5)


def test03_transmittance_is_exp_optical_depth():
    out = bake(aa_samples=1)
    want = np.exp(-SIGMA_T * analytic_depth())
    for c in range(3):
        np.testing.assert_allclose(out["transmittance"][..., c], want, rtol=1e-5)


@pytest.mark.parametrize("model", ["sun05", "sun05_exact"])
def test04_airlight_matches_per_ray_model(model):
    light, I0 = np.array([1.0, 3.0, -5.0]), 2.0
    out = bake(lights=[light], intensities=[[I0] * 3], model=model, aa_samples=1)
    d = world_dirs()
    to_light = light - CAM_POS
    Dsv = np.linalg.norm(to_light)
    cos_gamma = d @ to_light / Dsv
    want = I0 * _native.sun05_airlight(SIGMA_T, Dsv, cos_gamma, analytic_depth(), model=model)
    for c in range(3):
        np.testing.assert_allclose(out["airlight"][..., c], want, rtol=1e-4)


def test05_interior_pixels_filtered_equal_centre():
    # Smooth image: the antialiased bake agrees with the centre-sample bake.
    np.testing.assert_allclose(bake()["airlight"], bake(aa_samples=1)["airlight"], rtol=1e-2)


def test06_linear_in_intensity_and_albedo():
    one = bake(intensities=[[1.0, 1.0, 1.0]], aa_samples=1)["airlight"]
    three = bake(intensities=[[3.0, 3.0, 3.0]], aa_samples=1)["airlight"]
    np.testing.assert_allclose(three, 3.0 * one, rtol=1e-5)
    tinted = bake(intensities=[[1.0, 1.0, 1.0]], albedo=(1.0, 0.5, 0.25), aa_samples=1)["airlight"]
    np.testing.assert_allclose(tinted, one * np.array([1.0, 0.5, 0.25], dtype=np.float32), rtol=1e-5)


def test07_additive_over_lights():
    a = ([1.0, 3.0, -5.0], [2.0, 1.0, 0.5])
    b = ([-3.0, 0.0, -2.0], [0.3, 0.6, 0.9])
    # Exact with every edge sub-sample evaluated; the default clusters of sub-samples are
    # refined where their error estimate (which depends on all lights) exceeds 5e-4
    # (test_bake_edge_clusters.py), so edge pixels add up to that.
    for kw, rtol in (({"edge_cluster_tol": 0.0}, 1e-5), ({}, 1e-3)):
        both = bake(lights=[a[0], b[0]], intensities=[a[1], b[1]], **kw)["airlight"]
        sep = (bake(lights=[a[0]], intensities=[a[1]], **kw)["airlight"] +
               bake(lights=[b[0]], intensities=[b[1]], **kw)["airlight"])
        np.testing.assert_allclose(both, sep, rtol=rtol, atol=1e-9)


def test08_zero_density_is_clear():
    out = bake(sigma_t=0.0)
    assert np.all(out["airlight"] == 0.0)
    assert np.all(out["transmittance"] == 1.0)


def test09_no_lights_no_airlight():
    out = bake(lights=np.zeros((0, 3)), intensities=np.zeros((0, 3)))
    assert np.all(out["airlight"] == 0.0)


def test10_rows_top_first():
    # Empty scene, camera level; a light above the horizon brightens the upper rows.
    empty = (np.zeros((0, 3), np.float32), np.zeros((0, 3), np.uint32))
    out = bake(geometry=empty, lights=[[0.0, 4.0, -10.0]], intensities=[[5.0] * 3],
               cam_to_world=camera_matrix(np.eye(3), [0, 0, 0]))
    assert np.all(np.isinf(out["depth"]))
    assert np.all(out["transmittance"] == 0.0)
    La = out["airlight"][..., 0]
    assert La[: H // 2].mean() > 2.0 * La[H // 2:].mean()


def test11_misses_are_infinite():
    # A floor under the left half of the view only (world x < 0, camera level at origin).
    half = plane_z(PLANE_Z, x=(-1000.0, 0.0))
    out = bake(geometry=half, cam_to_world=camera_matrix(np.eye(3), [0, 0, 0]))
    assert np.all(np.isfinite(out["depth"][:, : W // 2]))
    assert np.all(np.isinf(out["depth"][:, W // 2:]))
    assert 0 < out["stats"]["supersampled_pixels"] <= 4 * H


def blackman_harris_cdf(x, w=1.5):
    """Cycles' Blackman-Harris film filter (support [-w, w]), integrated from -w to x."""
    t = np.linspace(-w, x, 20001)
    a = 2 * np.pi * (t / (2 * w) + 0.5)
    f = 0.35875 - 0.48829 * np.cos(a) + 0.14128 * np.cos(2 * a) - 0.01168 * np.cos(3 * a)
    tt = np.linspace(-w, w, 20001)
    aa = 2 * np.pi * (tt / (2 * w) + 0.5)
    ff = 0.35875 - 0.48829 * np.cos(aa) + 0.14128 * np.cos(2 * aa) - 0.01168 * np.cos(3 * aa)
    return np.trapz(f, t) / np.trapz(ff, tt)


EDGE_LIGHT = (0.0, 0.0, 20.0)  # behind the camera at the origin: A is flat near the axis


def _coverage_from_airlight(out, row, col, Dvp_hit):
    """Filter-weighted share of hits of pixel (row, col), from its airlight: the bake
    averages A over the samples, A = c A_hit + (1 - c) A_miss (centre-ray values; with
    the light right behind the camera A barely varies across the filter's +-1.5 px)."""
    d = (pixel_dirs_camera(FOV, W, H))[row, col]
    light = np.array(EDGE_LIGHT)
    Dsv = np.linalg.norm(light)
    cos_g = d @ light / Dsv
    A_hit, A_miss = (2.0 * _native.sun05_airlight(SIGMA_T, Dsv, cos_g, D, model="sun05_exact")
                     for D in (Dvp_hit, math.inf))
    return (out["airlight"][row, col, 0] - A_miss) / (A_hit - A_miss)


def test12_edge_pixels_follow_film_filter():
    # A vertical silhouette edge between columns W/2-1 and W/2. The airlight mixes hits and
    # misses by the filter-weighted coverage; the transmittance is the surface's own (the
    # mean over the samples that hit: exact for render * T + A over a black world).
    half = plane_z(PLANE_Z, x=(0.0, 1000.0))
    out = bake(geometry=half, cam_to_world=camera_matrix(np.eye(3), [0, 0, 0]), aa_samples=16,
               lights=(EDGE_LIGHT,))
    Tr = out["transmittance"][H // 2, :, 0]
    Dvp = -PLANE_Z / math.cos(0.5 * FOV / W)  # ~ near the axis
    Tr_hit = math.exp(-SIGMA_T * Dvp)
    assert Tr[W // 2] == pytest.approx(Tr_hit, rel=1e-3)
    assert Tr[W // 2 - 1] == pytest.approx(Tr_hit, rel=1e-3)
    for col, x in ((W // 2, -0.5), (W // 2 - 1, 0.5)):
        assert _coverage_from_airlight(out, H // 2, col, Dvp) == pytest.approx(
            1 - blackman_harris_cdf(x), abs=0.01)
    assert Tr[W // 2 + 2] == pytest.approx(math.exp(-SIGMA_T * out["depth"][H // 2, W // 2 + 2]), rel=1e-5)
    assert Tr[W // 2 - 3] == 0.0


@pytest.mark.parametrize("shift", [0.0, 0.13, 0.29, 0.41])
def test12b_horizontal_edge_coverage_is_resolved_to_1_over_N(shift):
    # A horizontal edge at a sub-pixel offset _shift_: with aa_samples = 4 the 16 samples
    # have 16 distinct rows, so the coverage is within ~1/32 of the filter's (a 4 x 4 grid
    # has 4 rows: errors up to ~1/8, measured as dark edge rows against Cycles).
    pix = 2.0 * -PLANE_Z * math.tan(0.5 * FOV) / W  # pixel size on the plane
    half = plane_z(PLANE_Z, y=(0.0, 1000.0))
    cam = camera_matrix(np.eye(3), [0, shift * pix, 0])  # the edge moves down by _shift_ px
    out = bake(geometry=half, cam_to_world=cam, aa_samples=4, lights=(EDGE_LIGHT,))
    Dvp = -PLANE_Z / math.cos(0.5 * FOV / W)
    for row in (H // 2 - 1, H // 2):
        x = (H // 2 + shift) - (row + 0.5)  # edge position relative to the row's centre, down
        want = blackman_harris_cdf(x)  # the hits lie above the edge: offsets < x
        got = _coverage_from_airlight(out, row, W // 2, Dvp)
        assert got == pytest.approx(want, abs=1 / 32 + 0.01), (row, x)


def test12c_clip_range_like_cycles():
    # Fog from the near plane (attenuated from there), surfaces beyond clip_end unseen,
    # depth still from the eye. Reference: the quadrature model from the moved origin.
    light = np.array([1.0, 3.0, -5.0])
    cam = camera_matrix(np.eye(3), [0, 0, 0])
    d = pixel_dirs_camera(FOV, W, H)
    cos_view = -d[..., 2]
    for clip_start, clip_end in ((1.5, 100.0), (1.5, 6.0)):
        out = bake(cam_to_world=cam, clip_start=clip_start, clip_end=clip_end, aa_samples=1,
                   model="quadrature")
        t_near = clip_start / cos_view
        depth = -PLANE_Z / cos_view
        seen = depth <= clip_end / cos_view
        np.testing.assert_allclose(out["depth"], np.where(seen, depth, np.inf), rtol=1e-5)
        o = t_near[..., None] * d
        sv = light - o
        Dsv = np.linalg.norm(sv, axis=-1)
        Dvp = np.where(seen, depth - t_near, np.inf)
        La = 2.0 * _native.sun05_airlight(SIGMA_T, Dsv, np.sum(d * sv, -1) / Dsv, Dvp, model="quadrature")
        np.testing.assert_allclose(out["airlight"][..., 0], La, rtol=1e-6)
        np.testing.assert_allclose(out["transmittance"][..., 0], np.exp(-SIGMA_T * Dvp), rtol=1e-5, atol=1e-7)
    # Defaults integrate from the eye: identical to clip_start = 0, clip_end = inf.
    a, b = bake(cam_to_world=cam), bake(cam_to_world=cam, clip_start=0.0, clip_end=math.inf)
    np.testing.assert_array_equal(a["airlight"], b["airlight"])
    for bad in ((-1.0, 10.0), (2.0, 2.0), (math.nan, 10.0), (1.0, math.nan)):
        with pytest.raises(ValueError, match="clip"):
            bake(cam_to_world=cam, clip_start=bad[0], clip_end=bad[1])


def test13_orthographic_rays_are_parallel():
    near = 0.1
    out = bake(cam_to_world=camera_matrix(np.eye(3), [0, 0, 2.0]),
               projection=orthographic(6.0, W, H, near=near))
    # Rays start on the near plane and all meet the floor at the same distance.
    np.testing.assert_allclose(out["depth"], 2.0 - PLANE_Z - near, rtol=1e-5)


def test14_models_agree_in_a_bake():
    ref = bake(model="quadrature", aa_samples=1)["airlight"]
    for model in ["sun05", "sun05_exact"]:
        got = bake(model=model, aa_samples=1)["airlight"]
        np.testing.assert_allclose(got, ref, rtol=2e-3 if model == "sun05" else 1e-5)
