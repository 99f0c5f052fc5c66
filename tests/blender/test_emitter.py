"""Particle emitter (addon/airlight/emitter.py): parabolic paths against the closed form,
determinism under scrubbing, keyframed emitters against Blender's own matrix_world, bake to
frames that survives save/reload, `blender -b -a` renders of the smoke, bad input, and the
per-Gaussian colour attribute that fog_object.gather() returns."""
import math
import os

import bpy
import numpy as np
import pytest
from mathutils import Euler, Matrix

from airlight import emitter, fog_object as fo
from conftest import build_plane_scene, draw_panel, exr_pass, read_exr, run_blender


@pytest.fixture
def scene():
    bpy.ops.wm.read_homefile(use_factory_startup=True, use_empty=True)
    scene = bpy.context.scene
    scene.render.fps, scene.render.fps_base = 24, 1.0
    scene.frame_start, scene.frame_end = 1, 60
    return scene


def _add(scene, **settings):
    assert bpy.ops.airlight.add_emitter() == {'FINISHED'}
    obj = bpy.context.active_object
    for key, value in settings.items():
        setattr(obj.airlight_emitter, key, value)
    return obj


def _target_world(obj):
    """World-space Gaussians of the emitter's target as the bake sees them."""
    g = fo.gather(bpy.context.evaluated_depsgraph_get())
    return g


def test01_add_creates_empty_and_target_fog_object(scene):
    scene.cursor.location = (1.0, 2.0, 0.5)
    obj = _add(scene)
    assert obj.type == 'EMPTY' and obj.airlight_emitter.is_emitter
    assert tuple(obj.location) == pytest.approx((1.0, 2.0, 0.5))
    target = obj.airlight_emitter.target
    assert fo.is_fog_object(target)
    assert target.data.attributes[fo.COLOR_ATTR].data_type == 'FLOAT_COLOR'
    assert emitter._menu_add in bpy.types.VIEW3D_MT_add._dyn_ui_initialize()
    for p in obj.airlight_emitter.bl_rna.properties:
        if p.identifier not in {"rna_type", "name"}:
            assert p.description, p.identifier


def test02_paths_match_the_closed_form(scene):
    """No spread, no spawn radius: particle k born at t_k = k / rate from the emitter's
    origin moves on p = L + R v tau + a tau^2 / 2; scale and amplitude linear in age."""
    obj = _add(scene, rate=10.0, lifetime=1.0, spread=0.0, radius=0.0, velocity=(1.0, 0.0, 0.5),
               acceleration=(0.0, 0.2, -1.0), scale=4.0, amplitude=0.6, scale_end=0.5,
               amplitude_end=0.25, frame_start=1, frame_end=1000, color=(0.2, 0.4, 0.9))
    obj.location = (1.0, -2.0, 3.0)
    obj.rotation_euler = (0.0, 0.0, math.pi / 2)  # local x -> world y
    frame = 62.2  # t = 61.2 / 24 = 2.55 s
    scene.frame_set(62, subframe=0.2)
    t = 61.2 / 24.0
    k = np.arange(16, 26)  # alive: k / 10 <= 2.55 and 2.55 - k / 10 < 1
    tau = t - k / 10.0
    R = np.array(Matrix.Rotation(math.pi / 2, 3, 'Z'))
    v = R @ np.array([1.0, 0.0, 0.5])
    expected = (np.array([1.0, -2.0, 3.0]) + np.outer(tau, v)
                + 0.5 * np.outer(tau ** 2, [0.0, 0.2, -1.0]))
    g = _target_world(obj)
    order = np.argsort(g["scales"])[::-1]  # youngest (largest a) first = largest k last
    c, a, amp = g["centres"][order][::-1], g["scales"][order][::-1], g["amplitudes"][order][::-1]
    assert len(c) == 10
    np.testing.assert_allclose(c, expected, atol=2e-5)
    np.testing.assert_allclose(a, 4.0 * (1.0 - 0.5 * tau), rtol=1e-5)
    np.testing.assert_allclose(amp, 0.6 * (1.0 - 0.75 * tau), rtol=1e-5)
    np.testing.assert_allclose(g["colors"], np.tile([0.2, 0.4, 0.9], (10, 1)), rtol=1e-6)
    # evaluate() at the same frame is what the handler wrote
    c2, a2, _, _ = emitter.evaluate(obj, scene, frame)
    np.testing.assert_allclose(np.sort(c2[:, 0]), np.sort(c[:, 0]), atol=2e-5)


def test03_spread_and_radius_statistics(scene):
    """Spawn points fill the ball of the radius; velocities scatter by `spread` around v."""
    p = dict(rate=20000.0, lifetime=10.0, duration=10.0, velocity=np.array([0.0, 0.0, 2.0]),
             spread=0.5, radius=0.3, acceleration=np.zeros(3), scale=1.0, amplitude=1.0,
             scale_end=1.0, amplitude_end=1.0, seed=7)
    c0, _, _, _ = emitter.simulate(0.5, p, lambda t: np.eye(4))  # particles of age 0 .. 0.5 s
    assert len(c0) == 10001
    p1 = dict(p, velocity=np.zeros(3), spread=0.0)
    start, _, _, k = emitter.simulate(0.5, p1, lambda t: np.eye(4))
    r = np.linalg.norm(start, axis=1)
    assert r.max() <= 0.3 and np.quantile(r, 0.5) == pytest.approx(0.3 * 0.5 ** (1 / 3), rel=0.03)
    tau = 0.5 - k / p["rate"]
    vel = (c0 - start)[tau > 0.1] / tau[tau > 0.1, None]
    np.testing.assert_allclose(vel.mean(0), [0.0, 0.0, 2.0], atol=0.03)
    np.testing.assert_allclose(vel.std(0), 0.5, rtol=0.04)
    # a different seed gives different particles
    other, _, _, _ = emitter.simulate(0.5, dict(p, seed=8), lambda t: np.eye(4))
    assert np.abs(other - c0).max() > 0.1


def test04_scrubbing_is_deterministic(scene):
    obj = _add(scene, rate=30.0, lifetime=2.0)
    scene.frame_set(10)
    first = [np.array(x) for x in fo.read(obj.airlight_emitter.target)]
    scene.frame_set(30)
    later = fo.read(obj.airlight_emitter.target)[0]
    scene.frame_set(10)
    again = fo.read(obj.airlight_emitter.target)
    for x, y in zip(first, again):
        np.testing.assert_array_equal(x, y)
    assert len(later) != len(first[0]) or np.abs(later[: len(first[0])] - first[0]).max() > 0
    # stepping 1..10 frame by frame gives the same as the jump
    for f in range(1, 11):
        scene.frame_set(f)
    np.testing.assert_array_equal(fo.read(obj.airlight_emitter.target)[0], first[0])


def test04b_two_emitters_share_one_target(scene):
    """A second emitter writing into the first one's fog object: the target holds both
    emitters' particles (each equal to its own evaluate()), in the target's object space."""
    first = _add(scene, rate=10.0, seed=1, color=(1.0, 0.0, 0.0))
    second = _add(scene, rate=7.0, seed=2, color=(0.0, 0.0, 1.0))
    extra = second.airlight_emitter.target
    second.airlight_emitter.target = first.airlight_emitter.target
    bpy.data.objects.remove(extra)
    second.location = (3.0, 0.0, 0.0)
    first.airlight_emitter.target.location = (0.0, 1.0, 0.0)
    scene.frame_set(30)
    g = fo.gather(bpy.context.evaluated_depsgraph_get())
    expected = [emitter.evaluate(o, scene) for o in (first, second)]
    assert len(g["centres"]) == sum(len(e[0]) for e in expected) > 20
    red = g["colors"][:, 0] > 0.5
    for mask, e in ((red, expected[0]), (~red, expected[1])):
        np.testing.assert_allclose(np.sort(g["centres"][mask], axis=0), np.sort(e[0], axis=0), atol=1e-5)


def test05_keyframed_emitter_emits_from_where_it_was(scene):
    """Velocity 0: each particle stays where it was born, i.e. at the emitter's world
    position (Blender's own matrix_world after frame_set) at its birth frame."""
    obj = _add(scene, rate=24.0, lifetime=100.0, spread=0.0, radius=0.0, velocity=(0.0, 0.0, 0.0),
               acceleration=(0.0, 0.0, 0.0), frame_start=1, frame_end=100)
    obj.rotation_mode = 'YXZ'
    for f, loc, rot in ((1, (0, 0, 0), (0, 0, 0)), (11, (2, 1, 0), (0.3, 0.2, 1.0)),
                        (21, (2, 3, 1), (0.5, -0.4, 2.0))):
        obj.location, obj.rotation_euler = loc, rot
        obj.keyframe_insert("location", frame=f)
        obj.keyframe_insert("rotation_euler", frame=f)
    expected = []
    for f in range(1, 21):
        scene.frame_set(f)
        expected.append(np.array(obj.matrix_world.translation))
    # track matrices: compare the full matrix with Blender's at a few frames
    track = emitter.matrix_track(obj, scene)
    for f in (4, 13, 17):
        scene.frame_set(f)
        np.testing.assert_allclose(track(np.array([(f - 1) / 24.0]))[0], np.array(obj.matrix_world),
                                   atol=1e-5)
    scene.frame_set(20)
    c = fo.read(obj.airlight_emitter.target)[0]  # target at the origin: local = world
    assert len(c) == 20  # one per frame (rate = fps)
    np.testing.assert_allclose(np.sort(c, axis=0), np.sort(np.array(expected), axis=0), atol=1e-4)
    # editing the animation is seen at once (birth matrices are cached per animation state)
    fc = next(f for f in obj.animation_data.action.fcurves
              if f.data_path == "location" and f.array_index == 0)
    fc.keyframe_points[1].co.y += 5.0
    fc.keyframe_points[1].handle_left.y += 5.0
    fc.keyframe_points[1].handle_right.y += 5.0
    fc.update()
    scene.frame_set(11)
    moved = np.array(obj.matrix_world.translation)
    assert moved[0] == pytest.approx(7.0)
    scene.frame_set(20)
    c = fo.read(obj.airlight_emitter.target)[0]
    assert np.linalg.norm(c - moved, axis=1).min() < 1e-4


def test06_bad_input(scene, capsys):
    obj = _add(scene)
    s = obj.airlight_emitter
    s.rate, s.lifetime, s.scale = 0.0, -1.0, -2.0  # clamped by the property limits
    assert s.rate > 0.0 and s.lifetime > 0.0 and s.scale > 0.0
    p = emitter.params(s, scene)
    for key, value in (("rate", 0.0), ("lifetime", -1.0), ("scale", float("nan")),
                       ("velocity", np.array([np.inf, 0.0, 0.0])), ("rate", 1e9)):
        with pytest.raises(emitter.EmitterError):
            emitter.simulate(1.0, dict(p, **{key: value}), lambda t: np.eye(4))
    # before the first frame: no particle, the target holds one Gaussian of amplitude 0
    s.frame_start = 20
    scene.frame_set(5)
    c, a, amp = fo.read(s.target)
    assert len(c) == 1 and amp[0] == 0.0 and a[0] > 0.0
    fo.validate("t", c, a, amp)  # a valid fog object for the bake
    # a broken handler input is printed, never raised
    s.target = None
    scene.frame_set(6)
    assert emitter.update_emitter(obj, scene) is None


def test07_gather_colors(scene):
    obj = _add(scene, color=(0.1, 0.5, 1.0), rate=50.0)
    scene.frame_set(20)
    g = fo.gather(bpy.context.evaluated_depsgraph_get())
    assert "colors" in g and g["colors"].shape == (len(g["scales"]), 3)
    assert g["colors"].dtype == np.float32
    np.testing.assert_allclose(g["colors"], np.tile([0.1, 0.5, 1.0], (len(g["scales"]), 1)), rtol=1e-6)
    # a fog object without colours gets the scene fog colour
    scene.airlight.color = (0.3, 0.3, 0.3)
    plain = fo.new_fog_object("Plain", scene.collection, centres=[(5, 5, 5), (6, 6, 6)])
    g = fo.gather(bpy.context.evaluated_depsgraph_get())
    names = len(g["scales"])
    assert g["colors"].shape == (names, 3)
    assert sorted(map(tuple, np.round(g["colors"], 5)))[0] == pytest.approx((0.1, 0.5, 1.0))
    assert (np.isclose(g["colors"], 0.3).all(axis=1)).sum() == 2
    # without any coloured object: None, and the tuple unpacking is unchanged
    bpy.data.objects.remove(obj.airlight_emitter.target)
    g = fo.gather(bpy.context.evaluated_depsgraph_get())
    c, a, amp = g
    assert g["colors"] is None and "colors" not in g and len(c) == 2
    # append keeps colours: painted Gaussians on a coloured object get the scene colour
    fo.write(plain, [(0, 0, 0)], 1.0, 0.1, colors=[(1.0, 0.0, 0.0)])
    fo.append(plain, [(1, 1, 1)], 1.0, 0.1)
    np.testing.assert_allclose(fo.read_colors(plain.data), [[1, 0, 0], [0.3, 0.3, 0.3]], rtol=1e-6)


def test08_bake_to_frames_survives_save_and_reload(scene, tmp_path):
    obj = _add(scene, rate=40.0, lifetime=1.0)
    scene.frame_start, scene.frame_end = 1, 12
    live = {}
    for f in (1, 6, 12):
        scene.frame_set(f)
        live[f] = [np.array(x) for x in fo.read(obj.airlight_emitter.target)]
    assert bpy.ops.airlight.emitter_bake() == {'FINISHED'}
    assert len(obj.airlight_emitter.baked) == 12
    # the baked frames are used: changing a setting no longer changes frame 6
    obj.airlight_emitter.rate = 5.0
    path = str(tmp_path / "baked.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.read_homefile(use_empty=True)
    bpy.ops.wm.open_mainfile(filepath=path)
    scene = bpy.context.scene
    obj = bpy.data.objects["Fog Emitter"]
    assert len(obj.airlight_emitter.baked) == 12
    for f in (1, 6, 12):
        scene.frame_set(f)
        for x, y in zip(live[f], fo.read(obj.airlight_emitter.target)):
            np.testing.assert_allclose(y, x, rtol=1e-6, atol=1e-7)
    n_meshes = len(bpy.data.meshes)
    bpy.context.view_layer.objects.active = obj
    assert bpy.ops.airlight.emitter_free_bake() == {'FINISHED'}
    assert len(bpy.data.meshes) == n_meshes - 12 and len(obj.airlight_emitter.baked) == 0
    scene.frame_set(6)  # live again, with the new rate
    assert len(obj.airlight_emitter.target.data.vertices) != len(live[6][0])


@pytest.mark.parametrize("baked", [False, True])
def test09_background_animation_render_has_moving_smoke(tmp_path, baked):
    """`blender -b file.blend -a` over 3 frames: the fog baked for each frame (render_pre,
    after frame_set, which runs the emitter's frame handler first) equals a bake of that
    frame made here, the smoke differs between frames, and the rendered images differ."""
    scene = build_plane_scene(tmp_path, size=(40, 30))
    scene.airlight.density = 0.001
    scene.render.engine = 'BLENDER_WORKBENCH'
    settings = scene.render.image_settings
    settings.file_format = 'OPEN_EXR'
    settings.color_depth = '32'
    scene.render.use_compositing = True
    scene.view_settings.view_transform = 'Standard'
    scene.frame_start, scene.frame_end = 1, 3
    scene.render.fps = 4  # a quarter second per frame: the smoke moves a lot
    scene.cursor.location = (0.0, 0.0, 0.3)
    obj = _add(scene, rate=16.0, lifetime=2.0, velocity=(0.6, 0.0, 0.4), scale=3.0, amplitude=3.0,
               frame_start=1, frame_end=3)
    bpy.ops.airlight.setup_compositor()
    if baked:
        bpy.context.view_layer.objects.active = obj
        assert bpy.ops.airlight.emitter_bake() == {'FINISHED'}
    scene.frame_set(1)
    blend = str(tmp_path / "smoke.blend")
    bpy.ops.wm.save_as_mainfile(filepath=blend)
    proc = run_blender(blend, "-o", str(tmp_path / "out_####"), "-a", timeout=300)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    for f in (1, 2, 3):
        assert f"Airlight: fog of frame {f} baked" in proc.stdout, proc.stdout[-3000:]
    airlight = {}
    for f in (1, 2, 3):
        baked_file = str(tmp_path / "cache" / f"fog_{f:04d}.exr")
        reference = str(tmp_path / f"ref_{f}.exr")
        assert bpy.ops.airlight.bake(frame=f, filepath=reference) == {'FINISHED'}
        airlight[f] = exr_pass(baked_file, "Airlight")
        np.testing.assert_allclose(airlight[f], exr_pass(reference, "Airlight"), rtol=1e-5, atol=1e-7)
        np.testing.assert_allclose(exr_pass(baked_file, "Transmittance"),
                                   exr_pass(reference, "Transmittance"), rtol=1e-5, atol=1e-7)
    assert airlight[3].max() > 1e-3
    assert np.abs(airlight[1] - airlight[2]).max() > 1e-3
    assert np.abs(airlight[2] - airlight[3]).max() > 1e-3
    images = [read_exr(str(tmp_path / f"out_{f:04d}.exr"))[0][..., :3] for f in (1, 2, 3)]
    assert np.abs(images[0] - images[1]).max() > 1e-3 and np.abs(images[1] - images[2]).max() > 1e-3


@pytest.mark.parametrize("panel", ["AIRLIGHT_PT_fog_tools", "AIRLIGHT_PT_emitter"])
def test10_panels_draw_every_setting(scene, panel):
    """The Fog Tools panel (N panel) and the emitter's Object properties panel draw without
    errors and show the airbrush / emitter settings and operators."""
    obj = _add(scene)
    with bpy.context.temp_override(object=obj, active_object=obj):
        seen = draw_panel(panel)
    if panel == "AIRLIGHT_PT_emitter":
        expected = {"rate", "velocity", "spread", "acceleration", "color", "lifetime", "scale",
                    "amplitude", "scale_end", "amplitude_end", "seed", "frame_start", "frame_end",
                    "target", "airlight.emitter_bake", "airlight.emitter_free_bake"}
    else:
        expected = {"airlight.airbrush", "airlight.fill_mesh", "airlight.add_emitter", "rate",
                    "speed", "diffusion", "damping", "fill_spacing", "scale_radius"}
    assert expected <= set(seen), expected - set(seen)
