"""bpy.ops.airlight.bake with fog objects (Gaussian fog, Fogshop): the Transmittance pass
against exp(-optical depth) from `_native.RbfMedium` (exact, unculled) on the pixel-centre
rays of interior pixels, rays computed here from the camera data; clear errors for empty or
invalid fog objects; without (render-visible) fog objects the passes are bit-identical."""
import os

import bpy
import numpy as np
import pytest

from airlight import fog_object, native, scene_export
from conftest import build_plane_scene, exr_pass

W, H = 48, 36
CENTRES = np.array([[0.0, 0.0, 1.0], [0.3, -0.2, 0.8], [-0.4, 0.3, 1.2], [0.1, 0.35, 0.6]])
SCALES = np.array([3.0, 4.0, 2.5, 5.0])
AMPLITUDES = np.array([1.5, 1.0, 0.8, 2.0])


def _bake(path):
    assert bpy.ops.airlight.bake(filepath=str(path)) == {'FINISHED'}
    return str(path)


def _pixel_rays(scene):
    """Eye, unit directions (H, W, 3) through pixel centres, near and hit distances on z = 0
    (camera at (0, 0, 2) looking straight down, sensor fit AUTO, landscape)."""
    cam = scene.camera.data
    scale = cam.sensor_width / cam.lens / W
    i = (np.arange(W) + 0.5 - W / 2) * scale
    j = (H / 2 - (np.arange(H) + 0.5)) * scale
    x, y = np.meshgrid(i, j)
    norm = np.sqrt(1.0 + x * x + y * y)
    d = np.stack([x, y, -np.ones_like(x)], axis=-1) / norm[..., None]
    return np.array([0.0, 0.0, 2.0]), d, cam.clip_start * norm, 2.0 * norm


def test01_transmittance_is_exp_minus_optical_depth(tmp_path):
    scene = build_plane_scene(tmp_path, size=(W, H))
    fog_object.new_fog_object("Fog", scene.collection, CENTRES, SCALES, AMPLITUDES)
    description = scene_export.export_scene(scene, bpy.context.evaluated_depsgraph_get())
    assert len(description["rbf_scales"]) == len(CENTRES)
    T_pass = exr_pass(_bake(tmp_path / "fog.exr"), "Transmittance")
    eye, d, t0, t1 = _pixel_rays(scene)
    medium = native.get().RbfMedium(CENTRES, SCALES, AMPLITUDES, beta0=scene.airlight.density)
    inner = (slice(1, H - 1), slice(1, W - 1))
    dirs = d[inner].reshape(-1, 3)
    p = eye + t0[inner].reshape(-1, 1) * dirs
    q = eye + t1[inner].reshape(-1, 1) * dirs
    expected = np.exp(-medium.optical_depth(p, q, culled=False)).reshape(H - 2, W - 2)
    for c in range(3):
        np.testing.assert_allclose(T_pass[inner][..., c], expected, rtol=2e-5, atol=1e-6)
    # The Gaussians matter: against the homogeneous fog alone.
    homogeneous = np.exp(-scene.airlight.density * (t1 - t0))[inner]
    assert np.max(homogeneous - expected) > 0.1


@pytest.mark.parametrize("case,message", [("empty", "has no Gaussians"),
                                          ("scale", "airlight_scale"),
                                          ("amplitude", "airlight_amplitude")])
def test02_empty_or_invalid_fog_object_is_a_clear_error(tmp_path, case, message):
    scene = build_plane_scene(tmp_path, size=(W, H))
    if case == "empty":
        fog_object.new_fog_object("Bad", scene.collection)
    else:
        scales = SCALES.copy()
        amplitudes = AMPLITUDES.copy()
        (scales if case == "scale" else amplitudes)[1] = -1.0
        fog_object.new_fog_object("Bad", scene.collection, CENTRES, scales, amplitudes)
    path = tmp_path / "x.exr"
    with pytest.raises(RuntimeError, match=message) as info:
        bpy.ops.airlight.bake(filepath=str(path))
    assert "'Bad'" in str(info.value)
    assert not os.path.exists(path)


def test03_no_visible_fog_object_is_bit_identical(tmp_path):
    scene = build_plane_scene(tmp_path, size=(W, H))
    before = _bake(tmp_path / "before.exr")
    description = scene_export.export_scene(scene, bpy.context.evaluated_depsgraph_get())
    assert not any(k.startswith("rbf_") for k in description)
    hidden = fog_object.new_fog_object("Hidden", scene.collection, CENTRES, SCALES, AMPLITUDES)
    hidden.hide_render = True
    after = _bake(tmp_path / "after.exr")
    for name in ("Airlight", "Transmittance"):
        assert np.array_equal(exr_pass(before, name), exr_pass(after, name))
    hidden.hide_render = False
    visible = _bake(tmp_path / "visible.exr")
    assert not np.array_equal(exr_pass(before, "Transmittance"), exr_pass(visible, "Transmittance"))


def test04_noise_properties_export_animate_and_bake(tmp_path):
    scene = build_plane_scene(tmp_path, size=(W, H))
    fog_object.new_fog_object("Fog", scene.collection, CENTRES, SCALES, AMPLITUDES)
    settings = scene.airlight
    assert settings.noise_amplitude == 0.0  # off by default
    plain = _bake(tmp_path / "plain.exr")
    # Keyframed amplitude and offset: the export reads them at the current frame.
    settings.noise_scale = 0.05
    settings.noise_amplitude = 0.0
    settings.keyframe_insert("noise_amplitude", frame=1)
    settings.noise_amplitude = 0.6
    settings.keyframe_insert("noise_amplitude", frame=11)
    settings.noise_offset = (0.0, 0.0, 0.0)
    settings.keyframe_insert("noise_offset", frame=1)
    settings.noise_offset = (2.0, 0.0, 0.0)
    settings.keyframe_insert("noise_offset", frame=11)
    scene.frame_set(1)
    description = scene_export.export_scene(scene, bpy.context.evaluated_depsgraph_get())
    assert description["noise_amplitude"] == 0.0
    off = _bake(tmp_path / "off.exr")
    for name in ("Airlight", "Transmittance"):  # amplitude 0: bit-identical
        assert np.array_equal(exr_pass(plain, name), exr_pass(off, name))
    scene.frame_set(11)
    description = scene_export.export_scene(scene, bpy.context.evaluated_depsgraph_get())
    assert description["noise_amplitude"] == pytest.approx(0.6)
    assert description["noise_scale"] == pytest.approx(0.05)
    assert description["noise_offset"] == pytest.approx((2.0, 0.0, 0.0))
    noisy = _bake(tmp_path / "noisy.exr")
    T0, T1 = exr_pass(plain, "Transmittance"), exr_pass(noisy, "Transmittance")
    assert not np.array_equal(T0, T1)
    assert np.all(np.isfinite(T1)) and np.all((T1 >= 0) & (T1 <= 1))


def test05_fog_colours_are_exported_when_gathered(tmp_path, monkeypatch):
    scene = build_plane_scene(tmp_path, size=(W, H))
    fog_object.new_fog_object("Fog", scene.collection, CENTRES, SCALES, AMPLITUDES)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    assert "rbf_albedo" not in scene_export.export_scene(scene, depsgraph)
    colours = np.tile([[1.0, 0.5, 0.25]], (len(CENTRES), 1))
    monkeypatch.setattr(fog_object, "gather", lambda dg, mesh_overrides=None: dict(centres=CENTRES, scales=SCALES,
                                                              amplitudes=AMPLITUDES, colors=colours))
    description = scene_export.export_scene(scene, depsgraph)
    np.testing.assert_array_equal(description["rbf_albedo"], colours)
    bad = colours.copy()
    bad[0, 0] = -1.0
    monkeypatch.setattr(fog_object, "gather", lambda dg, mesh_overrides=None: dict(centres=CENTRES, scales=SCALES,
                                                              amplitudes=AMPLITUDES, colors=bad))
    with pytest.raises(scene_export.ExportError, match="colours"):
        scene_export.export_scene(scene, depsgraph)


def test06_fog_object_resolution_reaches_the_bake(tmp_path):
    """scene.airlight.gaussian_resolution: Full is the per-pixel splat (Transmittance as
    exact as test01's), Quarter differs from it but stays within its interpolation error."""
    scene = build_plane_scene(tmp_path, size=(W, H))
    fog_object.new_fog_object("Fog", scene.collection, CENTRES, SCALES, AMPLITUDES)
    scene.airlight.model = 'SUN05'
    passes = {}
    for res in ('FULL', 'QUARTER'):
        scene.airlight.gaussian_resolution = res
        path = _bake(tmp_path / f"fog_{res}.exr")
        passes[res] = {name: exr_pass(path, name) for name in ("Airlight", "Transmittance")}
    eye, d, t0, t1 = _pixel_rays(scene)
    medium = native.get().RbfMedium(CENTRES, SCALES, AMPLITUDES, beta0=scene.airlight.density)
    inner = (slice(1, H - 1), slice(1, W - 1))
    dirs = d[inner].reshape(-1, 3)
    p = eye + t0[inner].reshape(-1, 1) * dirs
    q = eye + t1[inner].reshape(-1, 1) * dirs
    expected = np.exp(-medium.optical_depth(p, q, culled=False)).reshape(H - 2, W - 2)
    np.testing.assert_allclose(passes['FULL']["Transmittance"][inner][..., 0], expected, rtol=2e-5, atol=1e-6)
    quarter = passes['QUARTER']["Transmittance"][inner][..., 0]
    assert not np.array_equal(quarter, passes['FULL']["Transmittance"][inner][..., 0])
    np.testing.assert_allclose(quarter, expected, rtol=5e-2, atol=1e-4)
    full_a, quarter_a = passes['FULL']["Airlight"], passes['QUARTER']["Airlight"]
    np.testing.assert_allclose(quarter_a, full_a, rtol=5e-2, atol=1e-3 * full_a.max())


def _fog_pixels(scene):
    """Interior pixels whose centre ray passes within 0.3 m of a Gaussian centre."""
    eye, d, _, _ = _pixel_rays(scene)
    rel = CENTRES[None, None, :, :] - eye
    ts = np.einsum("hwk,hwnk->hwn", d, np.broadcast_to(rel, d.shape[:2] + rel.shape[2:]))
    dist = np.linalg.norm(rel - ts[..., None] * d[:, :, None, :], axis=-1)
    return np.any(dist < 0.3, axis=-1)


def test07_fog_object_with_sun_spot_and_anisotropic_phase(tmp_path):
    """Fog objects lit by a sun lamp (with and without a fog top), then + a spot light and
    Henyey-Greenstein anisotropy: bpy.ops.airlight.bake exports and bakes them (Automatic
    picks a model that takes Gaussians with that light and phase) and the Airlight pass is
    finite and brighter where the Gaussians are than the same bake without them."""
    import math
    from airlight import model_choice
    scene = build_plane_scene(tmp_path, size=(W, H), light=False)
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", 'SUN'))
    sun.data.energy = 3.0
    sun.rotation_euler = (math.radians(30.0), 0.0, math.radians(20.0))
    scene.collection.objects.link(sun)
    fog = fog_object.new_fog_object("Fog", scene.collection, CENTRES, SCALES, AMPLITUDES)
    where = _fog_pixels(scene)
    assert 20 < where.sum() < W * H - 20

    def bake_pair(name):
        fog.hide_render = True
        without = exr_pass(_bake(tmp_path / f"{name}_without.exr"), "Airlight")
        fog.hide_render = False
        depsgraph = bpy.context.evaluated_depsgraph_get()
        description = scene_export.export_scene(scene, depsgraph)
        assert len(description["rbf_scales"]) == len(CENTRES) and len(description["sun_directions"]) == 1
        with_fog = exr_pass(_bake(tmp_path / f"{name}.exr"), "Airlight")
        assert np.all(np.isfinite(with_fog)) and with_fog.max() > 0.0
        gain = (with_fog - without)[..., 0]
        assert np.median(gain[where]) > 0.05 * np.median(without[..., 0][where]), name
        assert np.median(np.abs(gain[~where])) < np.median(gain[where]), name
        return with_fog

    assert model_choice.choose(scene.airlight)[0] == "sun05"
    sun_only = bake_pair("sun")
    scene.airlight.use_fog_top = True
    scene.airlight.fog_top = 3.0
    topped = bake_pair("sun_top")
    assert not np.array_equal(sun_only, topped)  # the top attenuates the sunlight
    spot = bpy.data.objects.new("Spot", bpy.data.lights.new("Spot", 'SPOT'))
    spot.data.energy = 200.0
    spot.data.spot_size = math.radians(70.0)
    spot.location = (0.2, 0.1, 1.8)
    scene.collection.objects.link(spot)
    scene.airlight.phase = 'HENYEY_GREENSTEIN'
    scene.airlight.anisotropy = 0.5
    name = model_choice.choose(scene.airlight)[0]
    assert name in ("biri06", "pegoraro10", "quadrature")
    description = scene_export.export_scene(scene, bpy.context.evaluated_depsgraph_get())
    assert len(description["spot_positions"]) == 1 and description["phase"] == "hg"
    bake_pair("sun_spot_hg")


def test08_airlight_color_attribute_colours_the_bake(tmp_path):
    """A fog object's "airlight_color" point attribute reaches the bake: exported as
    rbf_albedo, it makes the Airlight pass red (R well above B) under a white light, where
    the same fog object without the attribute bakes grey. Automatic model (QUADRATURE
    refuses per-Gaussian colours); the fog is thin outside the Gaussians, so they dominate."""
    scene = build_plane_scene(tmp_path, size=(W, H))
    scene.objects["Lamp"].data.color = (1.0, 1.0, 1.0)
    scene.airlight.density = 0.01
    assert scene.airlight.model == 'AUTO' and tuple(scene.airlight.color) == (1.0, 1.0, 1.0)
    obj = fog_object.new_fog_object("Fog", scene.collection, CENTRES, SCALES, AMPLITUDES)
    assert "rbf_albedo" not in scene_export.export_scene(scene, bpy.context.evaluated_depsgraph_get())
    grey = exr_pass(_bake(tmp_path / "grey.exr"), "Airlight")

    red = np.tile(np.float32([[1.0, 0.1, 0.1]]), (len(CENTRES), 1))
    fog_object.write(obj, CENTRES, SCALES, AMPLITUDES, colors=red)
    description = scene_export.export_scene(scene, bpy.context.evaluated_depsgraph_get())
    np.testing.assert_array_equal(description["rbf_albedo"], red)
    reddish = exr_pass(_bake(tmp_path / "red.exr"), "Airlight")

    def channel_means(image):
        return [float(image[..., c].mean()) for c in range(3)]
    r, g, b = channel_means(grey)
    assert r > 0.0 and abs(r - b) <= 1e-3 * r and abs(r - g) <= 1e-3 * r
    r, g, b = channel_means(reddish)
    assert r > 3.0 * b and abs(g - b) <= 1e-3 * b
    # Red scatters what grey did: the colour changes the chroma, not the red channel (to the
    # Automatic 1 %: its refinement picks its exact terms from each ray's whole airlight).
    np.testing.assert_allclose(reddish[..., 0], grey[..., 0], rtol=0.01, atol=1e-7)


def _scripted_fog_mesh(scene, name, attributes=True):
    """A mesh built by a script as the README describes a fog object (vertices and the two
    point attributes, not through fog_object), linked to the scene and evaluated by the
    depsgraph before anything marks it as fog."""
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata([tuple(c) for c in CENTRES], [], [])
    if attributes:
        for attr, values in ((fog_object.SCALE_ATTR, SCALES), (fog_object.AMPLITUDE_ATTR, AMPLITUDES)):
            mesh.attributes.new(attr, 'FLOAT', 'POINT').data.foreach_set("value", values.astype(np.float32))
    obj = bpy.data.objects.new(name, mesh)
    scene.collection.objects.link(obj)
    bpy.context.evaluated_depsgraph_get()
    return obj


def test09_fog_marked_by_a_script_after_evaluation_is_baked(tmp_path):
    """is_fog set from a script after the depsgraph evaluated the mesh: the bake sees it
    (add-on properties do not tag the depsgraph, so the evaluated copy held is_fog False and
    the bake equalled one without the fog object), and equals the same fog made by
    fog_object.new_fog_object."""
    scene = build_plane_scene(tmp_path, size=(W, H))
    without = exr_pass(_bake(tmp_path / "without.exr"), "Transmittance")
    obj = _scripted_fog_mesh(scene, "Scripted")
    obj.airlight_fog.is_fog = True
    scripted = exr_pass(_bake(tmp_path / "scripted.exr"), "Transmittance")
    assert np.max(without - scripted) > 0.1
    bpy.data.objects.remove(obj)
    fog_object.new_fog_object("Fog", scene.collection, CENTRES, SCALES, AMPLITUDES)
    np.testing.assert_array_equal(scripted, exr_pass(_bake(tmp_path / "reference.exr"), "Transmittance"))


def test10_featureless_mesh_marked_by_a_script_is_refused(tmp_path):
    """A cube (no Gaussian attributes) marked as fog after evaluation: refused, naming the
    missing attribute, no file written (it used to bake as if it were not marked)."""
    scene = build_plane_scene(tmp_path, size=(W, H))
    bpy.ops.mesh.primitive_cube_add(size=0.5, location=(0.0, 0.0, 1.0))
    cube = bpy.context.active_object
    bpy.context.evaluated_depsgraph_get()
    cube.airlight_fog.is_fog = True
    path = tmp_path / "cube.exr"
    with pytest.raises(RuntimeError, match="missing the float point attribute 'airlight_scale'") as info:
        bpy.ops.airlight.bake(filepath=str(path))
    assert f"'{cube.name}'" in str(info.value)
    assert not os.path.exists(path)
