"""Gaussian fog at reduced resolution (`gaussian_resolution="half"` / `"quarter"`,
splat.h): on a scene whose depth edges cut through the fog (two walls standing
inside the cloud, a ground plane, the sky), the passes against the full-resolution bake
and against the exact double per-ray path (`RbfMedium.airlight` + `optical_depth_ray`,
Fogshop in double, independent of the splat); pixels on a depth edge equal the full
resolution's; "full" is the default and bit-identical to it; bad values raise."""
import math

import numpy as np
import pytest

import _native
from reference_util import rel_errors
from scene_util import (camera_matrix, gaussian_cloud, merge, perspective, pixel_dirs_camera, plane_y, plane_z,
                        rotation_x)

W, H = 320, 180
FOV = math.radians(60.0)
SIGMA_T = 0.004
LIGHTS = np.array([[-6.0, 5.0, -18.0], [8.0, 2.0, -32.0]])
INTENSITY = np.array([[400.0, 350.0, 300.0], [200.0, 200.0, 260.0]])
CLIP = 0.1


def geometry():
    """Ground y = -2, a near wall (z = -14, x in [-12, -2]) and a far wall (z = -26,
    x in [3, 14]), both up to y = 3: their silhouettes cross the cloud."""
    return merge([plane_y(-2.0, x=(-300.0, 300.0), z=(1.0, -400.0)),
                  plane_z(-14.0, x=(-12.0, -2.0), y=(-2.0, 3.0)),
                  plane_z(-26.0, x=(3.0, 14.0), y=(-2.0, 3.0))])


def bake(res=None, aa=4, noise=0.0, gauss=None):
    b, a, c = gauss if gauss is not None else gaussian_cloud()
    v, t = geometry()
    kw = dict(width=W, height=H, cam_to_world=camera_matrix(rotation_x(0.0), np.zeros(3)),
              projection=perspective(FOV, W, H, near=CLIP), vertices=v, triangles=t, light_positions=LIGHTS,
              light_intensities=INTENSITY, sigma_t=SIGMA_T, albedo=(0.9, 0.85, 0.8), clip_start=CLIP, threads=2,
              aa_samples=aa, rbf_centres=b, rbf_scales=a, rbf_amplitudes=c, noise_amplitude=noise)
    if res is not None:
        kw["gaussian_resolution"] = res
    return _native.bake(**kw)


def depth_edges(depth):
    """Pixels with a 4-neighbour whose depth differs by more than 20 % (or hit vs miss)."""
    d = np.where(np.isinf(depth), 1e30, depth)
    e = np.zeros(d.shape, bool)
    for axis in (0, 1):
        a = np.take(d, range(0, d.shape[axis] - 1), axis=axis)
        b = np.take(d, range(1, d.shape[axis]), axis=axis)
        jump = np.abs(a - b) > 0.2 * np.minimum(a, b)
        sl_a = [slice(None)] * 2
        sl_b = [slice(None)] * 2
        sl_a[axis] = slice(0, d.shape[axis] - 1)
        sl_b[axis] = slice(1, d.shape[axis])
        e[tuple(sl_a)] |= jump
        e[tuple(sl_b)] |= jump
    return e


@pytest.fixture(scope="module")
def full():
    return bake("full")


def test01_full_is_the_default_bit_for_bit(full):
    plain = bake(None)
    for key in ("airlight", "transmittance", "depth"):
        assert np.array_equal(plain[key], full[key])


# Near the lights the lattice's own light-factor criterion decides (splat.h: a
# Gaussian whose b^r stays 27 s pixels' angle x d from every light, per-Gaussian error
# tau = 2.5e-4 / 1e-3) instead of a 64-pixel exact margin, which at 320 x 180 covered
# much of the view: airlight mean 6.1e-5 / 2.1e-4 (was 2.9e-5 / 8.9e-5), max 8.9e-4 / 3.4e-3.
@pytest.mark.parametrize("res, mean_tol, p99_tol, max_tol",
                         [("half", 1e-4, 8e-4, 1e-2), ("quarter", 3e-4, 4e-3, 4e-2)])
def test02_reduced_against_full_with_depth_edges(full, res, mean_tol, p99_tol, max_tol):
    r = bake(res)
    assert np.all(np.isfinite(r["airlight"])) and np.all(np.isfinite(r["transmittance"]))
    assert np.array_equal(r["depth"], full["depth"])
    edges = depth_edges(full["depth"])
    assert edges.sum() > 300  # the walls' silhouettes and the horizon
    for key in ("airlight", "transmittance"):
        rel = rel_errors(r[key], full[key])
        print(f"{res} {key}: mean {rel.mean():.2e} p99 {np.percentile(rel, 99):.2e} max {rel.max():.2e} "
              f"({rel.size} px)")
        assert rel.mean() <= mean_tol and np.percentile(rel, 99) <= p99_tol and rel.max() <= max_tol, key
    # Not the full image by accident: the Gaussians are interpolated somewhere.
    assert not np.array_equal(r["airlight"], full["airlight"])


def wall_silhouettes(depth):
    """Pixels on a wall's silhouette: a wall hit next to a non-wall pixel (8-neighbours),
    both sides, away from the walls' base; the bake supersamples these (depth jumps)."""
    d = pixel_dirs_camera(FOV, W, H)
    wall = np.zeros(depth.shape, bool)
    for z in (14.0, 26.0):
        t = z / -d[..., 2]
        wall |= np.abs(depth - t) < 1e-3 * t
    pad = np.pad(wall, 1, mode="edge")
    any_wall = np.zeros_like(wall)
    any_other = np.zeros_like(wall)
    for dj in (-1, 0, 1):
        for di in (-1, 0, 1):
            n = pad[1 + dj:1 + dj + H, 1 + di:1 + di + W]
            any_wall |= n
            any_other |= ~n
    # Not where a wall stands on the ground (a crease: the depth is continuous there).
    finite = np.where(np.isinf(depth), 0.0, depth)
    above_base = finite * d[..., 1] > -1.8
    return any_wall & any_other & above_base


@pytest.mark.parametrize("res, tol", [("half", 8e-4), ("quarter", 4e-3)])
def test03_depth_edge_pixels_against_full_resolution(full, res, tol):
    """Pixels straddling a wall's silhouette are supersampled at every resolution: per
    sub-sample, the Gaussians a sub-sample's segment cuts exactly, those wholly in front
    of every sub-sample of a chunk from the lattice as for the centre samples (splat.h).
    Their error against the full bake stays within the interpolation's elsewhere (test02's
    p99 bound): no depth-edge artefact (without supersampling, aa = 1, these pixels err by
    tens of percent: checked below so that the test can tell)."""
    r = bake(res)
    edges = wall_silhouettes(full["depth"])
    assert edges.sum() > 100
    for key in ("airlight", "transmittance"):
        x = r[key][edges][:, 0].astype(np.float64)
        y = full[key][edges][:, 0].astype(np.float64)
        rel = np.abs(x - y) / np.maximum(np.abs(y), 1e-7 * np.abs(y).max())
        print(f"{res} edge pixels {key}: mean {rel.mean():.2e} max {rel.max():.2e} ({rel.size} px)")
        assert rel.max() <= tol, key
    no_aa = bake(res, aa=1)
    x = no_aa["transmittance"][edges][:, 0].astype(np.float64)
    y = full["transmittance"][edges][:, 0].astype(np.float64)
    assert np.max(np.abs(x - y) / np.maximum(np.abs(y), 1e-7)) > 10 * tol


@pytest.mark.parametrize("res, tol, median_tol", [("full", 2e-4, 1e-5), ("half", 1e-2, 1e-4), ("quarter", 3e-2, 5e-4)])
def test04_against_exact_per_ray_double_path(res, tol, median_tol):
    """Centre pixels (no supersampling) against RbfMedium's exact double Fogshop path;
    the depth-edge pixels included (aa_samples = 1: then they are plain pixels). The
    reduced resolutions' interpolation error of the optical depth T shows in the
    transmittance multiplied by T (up to ~4 here)."""
    b, a, c = gaussian_cloud()
    r = bake(res, aa=1)
    depth = r["depth"]
    rng = np.random.default_rng(5)
    edges = np.argwhere(depth_edges(depth))
    rows = np.concatenate([rng.integers(0, H, 300), edges[rng.integers(0, len(edges), 200), 0]])
    cols = np.concatenate([rng.integers(0, W, 300), edges[rng.integers(0, len(edges), 200), 1]])
    d = pixel_dirs_camera(FOV, W, H)[rows, cols]
    Dvp = depth[rows, cols].astype(np.float64)
    medium = _native.RbfMedium(b, a, c, beta0=SIGMA_T)
    # The segment [t0, Dvp] from the near plane: T over it, La(Dvp) - La(t0) scaled by the
    # attenuation to the near point (the bake's definition).
    t0 = CLIP / -d[:, 2]
    near = d * t0[:, None]
    T = medium.optical_depth_ray(near, d, np.maximum(Dvp - t0, 0.0), threads=2)
    Tr = r["transmittance"][rows, cols, 0]
    np.testing.assert_allclose(Tr, np.exp(-T), rtol=tol, atol=1e-6)
    hit = np.exp(-T) > 1e-3
    assert np.median(np.abs(Tr[hit] / np.exp(-T[hit]) - 1.0)) <= median_tol
    La = np.zeros(len(rows))
    La_near = np.zeros(len(rows))
    for l in range(len(LIGHTS)):
        w = 0.9 * INTENSITY[l, 0]
        La += w * medium.airlight(LIGHTS[l], np.zeros(3), d, Dvp, threads=2)
        La_near += w * medium.airlight(LIGHTS[l], np.zeros(3), d, t0, threads=2)
    T_near = medium.optical_depth_ray(np.zeros((len(rows), 3)), d, t0, threads=2)
    ref = np.exp(T_near) * (La - La_near)
    np.testing.assert_allclose(r["airlight"][rows, cols, 0], ref, rtol=tol, atol=1e-6 * ref.max())
    assert np.median(np.abs(r["airlight"][rows, cols, 0] / ref - 1.0)) <= median_tol


def test07_gaussian_around_the_eye():
    """A broad Gaussian around the camera reaches the near clip plane: its near segment
    [0, t0] is interpolated from the lattice, its far part classified like the others."""
    b, a, c = gaussian_cloud()
    gauss = (np.vstack([b, [[0.3, 0.2, -0.5]]]), np.append(a, 0.3), np.append(c, 0.3))
    full_e = bake("full", gauss=gauss)
    assert not np.array_equal(full_e["transmittance"], bake("full")["transmittance"])
    for res, p99_tol in (("half", 8e-4), ("quarter", 4e-3)):
        r = bake(res, gauss=gauss)
        for key in ("airlight", "transmittance"):
            rel = rel_errors(r[key], full_e[key])
            print(f"eye Gaussian, {res} {key}: mean {rel.mean():.2e} p99 {np.percentile(rel, 99):.2e} "
                  f"max {rel.max():.2e}")
            assert np.percentile(rel, 99) <= p99_tol, key


def test05_noise_at_reduced_resolution():
    full_n = bake("full", noise=0.4)
    r = bake("quarter", noise=0.4)
    for key in ("airlight", "transmittance"):
        rel = rel_errors(r[key], full_n[key])
        print(f"noise 0.4, quarter {key}: mean {rel.mean():.2e} p99 {np.percentile(rel, 99):.2e} max {rel.max():.2e}")
        assert rel.mean() <= 3e-3 and np.percentile(rel, 99) <= 5e-2, key


def test06_bad_resolution_raises():
    with pytest.raises(ValueError, match="gaussian_resolution"):
        bake("eighth")


def test08_broad_gaussians_cut_by_the_surface():
    """Broad Gaussians (1/a 4..10 m, bench_rbf.py's 34-Gaussian scene) that the ground and
    the walls cut: at reduced resolution their light side is interpolated where it does not
    depend on the depth (from the lattice where b^r lies before the surface, from a 4x4
    block's corner pixels where the surface lies before b^r and the block's surface is a
    smooth patch, GaussianSplat::cut_light_factor); against the full-resolution bake."""
    rng = np.random.default_rng(5)
    n = 20
    gauss = (np.column_stack([rng.uniform(-18, 18, n), rng.uniform(-2, 5, n), rng.uniform(-45, -8, n)]),
             1.0 / rng.uniform(4.0, 10.0, n), rng.uniform(0.005, 0.02, n))
    full_b = bake("full", gauss=gauss)
    for res, mean_tol, p99_tol, max_tol in (("half", 5e-5, 5e-4, 5e-3), ("quarter", 1e-4, 1e-3, 5e-3)):
        r = bake(res, gauss=gauss)
        for key in ("airlight", "transmittance"):
            rel = rel_errors(r[key], full_b[key])
            print(f"broad Gaussians, {res} {key}: mean {rel.mean():.2e} p99 {np.percentile(rel, 99):.2e} "
                  f"max {rel.max():.2e}")
            assert rel.mean() <= mean_tol and np.percentile(rel, 99) <= p99_tol and rel.max() <= max_tol, key
        assert not np.array_equal(r["airlight"], full_b["airlight"])
