"""Whole bakes at extremes the kernels' own stability suite (test_stability.py) does not
reach: dense uniform fog on edge pixels, and a fog-object Gaussian far wider and denser
than fog. Every value is finite and in range, and each equals a reference: the bake with
every edge sub-sample evaluated (edge_cluster_tol = 0), the closed-form transmittance of
uniform fog, or the Gaussians' exact double optical depth (RbfMedium, not the bake's
float kernels); where the fast kernels cannot be accurate the bake refuses with a message."""
import math

import numpy as np
import pytest

import _native
from scene_util import camera_matrix, merge, perspective, pixel_dirs_camera, plane_y, plane_z, rotation_x

W, H = 48, 32
FOV = math.radians(60.0)
EYE = np.array([0.0, 1.5, 0.0])


def scene(**kw):
    """Ground y = 0 and a wall z = -12 (x in [-3, 3], up to y = 3) crossing the view: depth
    edges (silhouette, horizon) for the edge samples; camera at EYE looking down -z."""
    v, t = merge([plane_y(0.0, x=(-200.0, 200.0), z=(5.0, -400.0)),
                  plane_z(-12.0, x=(-3.0, 3.0), y=(0.0, 3.0))])
    args = dict(width=W, height=H, cam_to_world=camera_matrix(rotation_x(-0.15), EYE),
                projection=perspective(FOV, W, H, near=0.1), vertices=v, triangles=t,
                light_positions=np.array([[1.0, 2.5, -8.0]]), light_intensities=np.array([[200.0, 180.0, 160.0]]),
                sigma_t=0.05, albedo=(0.9, 0.9, 0.9), clip_start=0.1, clip_end=1000.0, threads=2, aa_samples=8)
    args.update(kw)
    return args


def finite_in_range(r):
    A, T = r["airlight"], r["transmittance"]
    assert np.isfinite(A).all() and (A >= 0.0).all()
    assert np.isfinite(T).all() and (T >= 0.0).all() and (T <= 1.0).all()


@pytest.mark.parametrize("sigma_t", [2.0, 1e3, 1e6])
def test01_dense_uniform_fog_on_edge_pixels(sigma_t):
    """An edge pixel's sub-samples share their cluster's fog, the transmittance rescaled by
    the background extinction over each sample's own segment: in fog this dense the
    cluster's transmittance underflows while that factor overflows, and the product was
    NaN (sigma_t >= 1e3). It equals the bake that evaluates every sub-sample."""
    clustered = _native.bake(**scene(sigma_t=sigma_t))
    reference = _native.bake(**scene(sigma_t=sigma_t, edge_cluster_tol=0.0))
    finite_in_range(clustered)
    assert clustered["stats"]["supersampled_pixels"] > 20
    np.testing.assert_allclose(clustered["transmittance"], reference["transmittance"], rtol=1e-5, atol=1e-12)
    np.testing.assert_allclose(clustered["airlight"], reference["airlight"], rtol=2e-3,
                               atol=1e-6 * max(reference["airlight"].max(), 1e-30))
    # Off the edges: the closed form exp(-sigma_t (depth - t0)) (0 where nothing is hit).
    d = pixel_dirs_camera(FOV, W, H)
    t0 = 0.1 / -d[..., 2]
    depth = clustered["depth"]
    exact = np.where(np.isinf(depth), 0.0, np.exp(-sigma_t * (depth - t0)))
    T = clustered["transmittance"][..., 0]
    centre = np.abs(T - exact) <= 1e-6 * np.maximum(exact, 1e-300) + 1e-30
    assert centre.mean() > 0.8  # all but the edge pixels


def test02_wide_dense_gaussian_around_the_camera_is_refused_by_fogshop():
    """A Gaussian 1e8 m wide with peak density 1 /m holds the camera in its core: on the
    short segments from there the float kernels' erfc difference cancels (it gave a
    transmittance of 0.72 where the exact one is ~e^-8, and an infinite airlight on edge
    pixels). Fogshop refuses it with what to do; the quadrature model bakes it and its
    transmittance is the exact double optical depth's."""
    g = dict(rbf_centres=np.array([[0.0, 0.0, -20.0]]), rbf_scales=np.array([1e-8]),
             rbf_amplitudes=np.array([1.0]))
    with pytest.raises(ValueError, match="holds the camera or a light in its core.*quadrature"):
        _native.bake(**scene(model="sun05", **g))
    r = _native.bake(**scene(model="quadrature", aa_samples=1, **g))
    finite_in_range(r)
    medium = _native.RbfMedium(g["rbf_centres"], g["rbf_scales"], g["rbf_amplitudes"], beta0=0.05)
    cam = camera_matrix(rotation_x(-0.15), EYE)
    d = pixel_dirs_camera(FOV, W, H).reshape(-1, 3) @ cam[:3, :3].T
    t0 = 0.1 / (d @ -cam[:3, 2])
    depth = r["depth"].reshape(-1)
    hit = np.isfinite(depth)
    tau = medium.optical_depth_ray(EYE + t0[hit, None] * d[hit], d[hit], depth[hit] - t0[hit], culled=False)
    np.testing.assert_allclose(r["transmittance"][..., 0].reshape(-1)[hit], np.exp(-tau), rtol=1e-5, atol=1e-12)
    assert tau.min() > 2.5  # the blob is there: ~1 /m over the nearest segment (~3 m of ground)


def test03_dense_gaussian_seen_from_outside_is_baked():
    """A blob as dense (optical depth 1.8e6 through its centre) but 1 m wide, 5 m from the
    camera and 3.3 m from the light: no segment starts in its core, the kernels' erfc values
    are not both near 1, and Fogshop bakes it: finite, opaque through its core, and the
    uniform fog's transmittance where the view misses it."""
    g = dict(rbf_centres=np.array([[0.0, 1.5, -5.0]]), rbf_scales=np.array([1.0]), rbf_amplitudes=np.array([1e6]),
             gaussian_resolution="quarter")
    r = _native.bake(**scene(model="sun05", **g))
    finite_in_range(r)
    plain = _native.bake(**scene(model="sun05"))
    T, T0 = r["transmittance"][..., 0], plain["transmittance"][..., 0]
    assert T[H // 2 - 2:H // 2 + 2, W // 2 - 1:W // 2 + 1].max() < 1e-30  # through the blob's core
    corner = (slice(0, 4), slice(0, 4))  # far from the blob's image
    np.testing.assert_allclose(T[corner], T0[corner], rtol=1e-6)
