"""homogeneous_resolution "half" / "quarter" (bake.cpp lattice_band): the homogeneous airlight
on a 2 / 4-pixel lattice, interpolated where smooth. References: the exact per-pixel bake
("full", itself checked against quadrature in test_bake_passes.py, test_bake_F_table.py and
test_bake_sun_lamps.py) and, independently, the quadrature model on analytic rays
(scene_util's camera, analytic floor depth)."""
import math

import numpy as np
import pytest

import _native
from reference_util import rel_errors
from scene_util import camera_matrix, merge, perspective, pixel_dirs_camera, plane_y, plane_z, rotation_x

W, H = 480, 270
FOV = math.radians(60.0)
TILT = math.radians(-4.0)
CAM = np.array([0.0, 0.0, 2.0])  # floor z = 0, camera looks along -Z, pitched down: the horizon is in view
I0 = 500.0 / (4.0 * math.pi)


def scene(walls=False, lights=((-6.0, 3.0, -25.0), (5.0, 2.5, -40.0), (0.0, 6.0, -60.0)), **kw):
    # World: y up, the floor is the plane y = -2 (x-z), the camera at the origin looks down -Z.
    parts = [plane_y(-2.0, x=(-2000.0, 2000.0), z=(-2000.0, 2000.0))]
    if walls:
        parts += [plane_z(-25.0, x=(-16.0, -3.0), y=(-2.0, 4.0)), plane_z(-50.0, x=(2.0, 22.0), y=(-2.0, 4.0))]
    v, t = merge(parts)
    args = dict(width=W, height=H, cam_to_world=camera_matrix(rotation_x(TILT), [0.0, 0.0, 0.0]),
                projection=perspective(FOV, W, H), vertices=v, triangles=t,
                light_positions=np.array(lights, float), light_intensities=np.full((len(lights), 3), I0),
                sigma_t=0.01, albedo=(0.9, 0.8, 0.7), clip_start=0.1, clip_end=1000.0, threads=2)
    args.update(kw)
    return args


CASES = {
    "lights over a floor": {},
    "walls (depth edges)": {"walls": True},
    "lights 0.25 m above the floor": {"lights": ((-3.0, -1.75, -10.0), (2.0, -1.75, -20.0), (0.0, -1.9, -6.0))},
    "thick fog": {"sigma_t": 0.3},
    "from the eye": {"clip_start": 0.0},
    "sun lamp and a point light": {"lights": ((1.0, 1.0, -15.0),), "sun_directions": np.array([[0.3, -1.0, -0.4]]),
                                   "sun_irradiances": np.array([[2.0, 2.0, 2.0]]), "fog_top": 3.0},
}


@pytest.mark.parametrize("case", sorted(CASES))
@pytest.mark.parametrize("resolution", ["half", "quarter"])
def test01_lattice_against_the_exact_per_pixel_bake(case, resolution):
    kw = scene(**CASES[case])
    exact = _native.bake(**kw)
    lat = _native.bake(**kw, homogeneous_resolution=resolution)
    # Depth and transmittance are never interpolated.
    np.testing.assert_array_equal(lat["depth"], exact["depth"])
    np.testing.assert_array_equal(lat["transmittance"], exact["transmittance"])
    r = rel_errors(lat["airlight"], exact["airlight"], channel=None)
    mean, mx = r.mean(), r.max()
    # Cells are checked at their centres to 5e-4 (bake.cpp); measured max 1.5e-3 (street, quarter).
    assert mx < 3e-3, (case, mx)
    assert mean < 1e-4, (case, mean)
    # Something was interpolated (else the test would not test the lattice).
    assert np.mean(np.all(lat["airlight"] == exact["airlight"], axis=-1)) < 0.9


def test02_exact_near_lights_and_at_depth_edges():
    kw = scene(walls=True)
    exact = _native.bake(**kw)
    lat = _native.bake(**kw, homogeneous_resolution="quarter")
    # Exact: the per-pixel model's value (up to float rounding: the SIMD path's lanes and its
    # scalar remainder may round a dot product differently).
    same = np.all(np.abs(lat["airlight"] - exact["airlight"]) <= 1e-6 * exact["airlight"], axis=-1)
    # Pixels within 5 degrees of a light's direction are exact.
    d = pixel_dirs_camera(FOV, W, H) @ rotation_x(TILT).T
    for light in kw["light_positions"]:
        u = light / np.linalg.norm(light)
        near = d @ u > math.cos(math.radians(5.0))
        assert near.sum() > 100
        assert same[near].all()
    # Depth edges (the supersampled pixels differ from their centre sample): the wall silhouettes.
    no_aa = _native.bake(**kw, aa_samples=1)
    no_aa_lat = _native.bake(**kw, aa_samples=1, homogeneous_resolution="quarter")
    depth = no_aa["depth"]
    key = np.where(np.isinf(depth), 0.0, 1.0 / depth)
    jump = np.zeros_like(same)
    jump[:, 1:] |= np.abs(np.diff(key, axis=1)) > 0.05 * np.maximum(key[:, 1:], key[:, :-1])
    jump[1:, :] |= np.abs(np.diff(key, axis=0)) > 0.05 * np.maximum(key[1:, :], key[:-1, :])
    assert jump.sum() > 100
    np.testing.assert_allclose(no_aa_lat["airlight"][jump], no_aa["airlight"][jump], rtol=1e-6)


def test03_lattice_against_quadrature_on_analytic_rays():
    # Independent of the bake's camera and table: the quadrature model on the pixel centres'
    # rays (scene_util), floor depth in closed form, fog from the near plane.
    kw = scene(aa_samples=1, clip_start=0.0)
    lat = _native.bake(**kw, homogeneous_resolution="quarter")
    d = pixel_dirs_camera(FOV, W, H) @ rotation_x(TILT).T
    rows = np.arange(H // 2, H, 9)  # below the horizon: the floor
    dd = d[rows].reshape(-1, 3)
    Dvp = np.where(dd[:, 1] < 0, -2.0 / np.minimum(dd[:, 1], -1e-12), np.inf)
    ref = np.zeros((len(dd), 3))
    for light in kw["light_positions"]:
        Dsv = np.linalg.norm(light)
        cos_g = dd @ (light / Dsv)
        La = _native.sun05_airlight(kw["sigma_t"], Dsv, cos_g, Dvp, model="quadrature")
        ref += np.outer(La, np.array(kw["albedo"]) * I0)
    got = lat["airlight"][rows].reshape(-1, 3)
    r = np.abs(got - ref) / ref
    assert np.all(np.isfinite(got))
    assert r.max() < 3e-3 and r.mean() < 1e-4, (r.max(), r.mean())


def test04_other_cases_ignore_it_and_bad_values_are_refused():
    kw = scene()
    # Spots, Gaussians, other models and orthographic cameras: exact per pixel, unchanged.
    for extra in ({"model": "sun05_exact"},
                  {"spot_positions": np.array([[0.0, 3.0, -20.0]]), "spot_axes": np.array([[0.0, -1.0, 0.0]]),
                   "spot_intensities": np.array([[I0, I0, I0]]), "spot_size": np.array([1.0]),
                   "spot_blend": np.array([0.2])},
                  {"rbf_centres": np.array([[0.0, 0.0, -30.0]]), "rbf_scales": np.array([0.3]),
                   "rbf_amplitudes": np.array([0.02])}):
        a = _native.bake(**kw, **extra)
        b = _native.bake(**kw, **extra, homogeneous_resolution="quarter")
        np.testing.assert_array_equal(a["airlight"], b["airlight"])
    with pytest.raises(ValueError, match="homogeneous_resolution"):
        _native.bake(**kw, homogeneous_resolution="eighth")
