"""Per-light passes from one bake (`light_pass_index`): each pass against the bake of its
lights alone (an independent evaluation of the same model), and the passes' sum against the
total, over every light type, the lights' Radius and IES profiles, volumetric shadows, edge
supersampling, near clipping, the models that evaluate per ray and an orthographic camera;
the combinations the single bake cannot take are refused."""
import math

import numpy as np
import pytest

import _native
from scene_util import camera_matrix, merge, orthographic, perspective, quad
from test_bake_shadow_film import box, camera, street

W, H = 48, 32
FOV = math.radians(70.0)

POINTS = dict(light_positions=np.array([[2.0, 8.0, 5.0], [-5.0, 18.0, 3.5]]),
              light_intensities=np.array([[300.0, 250.0, 200.0], [200.0, 220.0, 260.0]]))
SPOTS = dict(spot_positions=np.array([[-2.0, 10.0, 5.0]]), spot_axes=np.array([[0.0, -0.3, -1.0]]),
             spot_intensities=np.array([[900.0, 800.0, 700.0]]), spot_size=np.array([1.2]),
             spot_blend=np.array([0.3]), spot_spread=np.array([math.pi]))
SUNS = dict(sun_directions=np.array([[0.3, 0.5, -1.0]]), sun_irradiances=np.array([[2.0, 2.2, 2.5]]))
KINDS = (("light_positions", "light_intensities", "light_radii", "light_shadows"),
         ("spot_positions", "spot_axes", "spot_intensities", "spot_size", "spot_blend", "spot_spread",
          "spot_radii", "spot_profiles", "spot_profile_in_cone", "spot_profile_extent", "spot_shadows"),
         ("sun_directions", "sun_irradiances", "sun_shadows"))


def scene(**extra):
    v, t = merge(street())
    args = dict(width=W, height=H, cam_to_world=camera(), projection=perspective(FOV, W, H, 0.5, 1000.0),
                vertices=v, triangles=t, sigma_t=0.08, albedo=(0.9, 0.8, 0.7), threads=2, clip_start=0.5,
                clip_end=1000.0, aa_samples=4, **POINTS)
    args.update(extra)
    return args


def light_count(args):
    return [len(args[keys[0]]) if args.get(keys[0]) is not None else 0 for keys in KINDS]


def only(args, keep):
    """_args_ with the lights whose flat index (points, spots, suns) is in _keep_."""
    out, start = dict(args), 0
    for keys, n in zip(KINDS, light_count(args)):
        mask = np.array([start + i in keep for i in range(n)], dtype=bool)
        start += n
        if n == 0:
            continue
        for key in keys:
            if out.get(key) is not None:
                out[key] = np.asarray(out[key])[mask]
        if not mask.any() and keys[0] != "light_positions":
            for key in keys:
                out.pop(key, None)
    return out


def check(args, index=None, tol=1e-4):
    n = sum(light_count(args))
    index = list(range(n)) if index is None else index
    result = _native.bake(**args, light_pass_index=np.array(index))
    total, passes = result["airlight"].astype(np.float64), result["light_airlight"].astype(np.float64)
    assert passes.shape == (max(index) + 1, H, W, 3)
    scale = np.percentile(total, 99)
    assert scale > 0.0
    # The total is the plain bake's, bit for bit, and the passes sum to it.
    assert np.array_equal(result["airlight"], _native.bake(**args)["airlight"])
    lit = [i for i in range(n) if index[i] >= 0]
    if len(lit) == n:
        assert np.abs(passes.sum(axis=0) - total).max() < 1e-5 * scale
    for g in range(passes.shape[0]):
        alone = _native.bake(**only(args, {i for i in range(n) if index[i] == g}))["airlight"].astype(np.float64)
        d = np.abs(passes[g] - alone)
        assert d.max() < tol * scale, (g, d.max() / scale)
        assert alone.max() > 1e-3 * scale  # every pass has light of its own
    return passes


def test_point_lights():
    check(scene())


def test_every_light_type():
    check(scene(**SPOTS, **SUNS))


def test_two_lights_in_one_pass_and_a_light_in_none():
    passes = check(scene(**SPOTS, **SUNS), index=[0, 1, 0, -1])
    assert passes.shape[0] == 2


def test_radius_and_profile():
    profile = np.array([[0.4, 0.0, 1.2, 0.0, -0.3]])
    check(scene(**SPOTS, light_radii=np.array([0.6, 0.0]), spot_radii=np.array([0.4]), spot_profiles=profile,
                spot_profile_in_cone=np.array([True])))


@pytest.mark.parametrize("crossings", ["film", "traced"])
def test_volumetric_shadows(crossings):
    check(scene(**SPOTS, **SUNS, shadows=True, shadow_crossings=crossings, light_shadows=np.array([True, False])))


@pytest.mark.parametrize("model", ["sun05_exact", "biri06", "pegoraro10", "quadrature"])
def test_models(model):
    check(scene(**SPOTS, **SUNS, model=model, table_size=512 if model == "biri06" else 256))


def test_no_supersampling_and_no_clustering():
    check(scene(aa_samples=1))
    check(scene(edge_cluster_tol=0.0))


def test_orthographic_camera():
    check(scene(**SPOTS, projection=orthographic(30.0, W, H, 0.5, 1000.0)))


def test_refused_where_one_bake_cannot_split_the_lights():
    args = scene()
    with pytest.raises(ValueError, match="homogeneous resolution"):
        _native.bake(**args, homogeneous_resolution="half", light_pass_index=np.array([0, 1]))
    with pytest.raises(ValueError, match="fog objects"):
        _native.bake(**args, rbf_centres=np.array([[0.0, 10.0, 2.0]]), rbf_scales=np.array([0.5]),
                     rbf_amplitudes=np.array([0.2]), light_pass_index=np.array([0, 1]))
    with pytest.raises(ValueError, match="whole image"):
        _native.bake(**args, model="baseline", light_pass_index=np.array([0, 1]))


@pytest.mark.parametrize("index, match", [([0], "one value per light"), ([0, -2], "not a pass index"),
                                          ([0, 0.5], "not a pass index"), ([0, float("nan")], "not a pass index")])
def test_bad_index(index, match):
    with pytest.raises(ValueError, match=match):
        _native.bake(**scene(), light_pass_index=np.array(index))
