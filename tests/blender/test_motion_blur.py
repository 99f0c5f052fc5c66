"""Motion blur: background renders and Bake Fog bake the fog at instants spread over the
shutter and average them (scene.airlight.motion_samples, bake.shutter_offsets,
prepare_views' evaluate_at), so that the fog passes blur at moving silhouettes as the render
does. Interactive renders cannot set the frame from their thread: they bake the frame's
instant, and the panel says so.

The reference is Cycles: a pole moving across an empty world, rendered with motion blur;
its alpha is each pixel's coverage over the shutter. The shutter samples' scenes must give
the same coverage (the fraction of them whose centre ray hits the pole)."""


import bpy
import numpy as np
import pytest

from airlight import bake
from conftest import coverage_errors, exr_pass, hit_coverage, poles_scene, read_exr, run_blender


def _moving_pole_scene(tmp_path, position='CENTER', shutter=1.0):
    scene, (pole,) = poles_scene(tmp_path, [((-1.0, 3.0, 1.0), (0.15, 0.15, 6.0))], 256)
    scene.cycles.filter_width = 0.01  # (a point filter: the bake's hit masks have none)
    for frame, x in ((1, -1.0), (3, 1.0)):  # 1 m per frame: ~14 px per frame at 3 m
        pole.location.x = x
        pole.keyframe_insert("location", frame=frame)
    for fcurve in pole.animation_data.action.fcurves:
        for key in fcurve.keyframe_points:
            key.interpolation = 'LINEAR'
    scene.frame_start, scene.frame_end = 1, 3
    scene.frame_set(2)
    scene.render.use_motion_blur = True
    scene.render.motion_blur_shutter = shutter
    scene.cycles.motion_blur_position = position
    return scene


def test01_shutter_offsets():
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    assert bake.shutter_offsets(scene) == []
    scene.render.use_motion_blur = True
    scene.render.motion_blur_shutter = 0.5
    scene.airlight.motion_samples = 4
    scene.render.engine = 'CYCLES'
    scene.cycles.motion_blur_position = 'CENTER'
    assert bake.shutter_offsets(scene) == pytest.approx([-0.1875, -0.0625, 0.0625, 0.1875])
    scene.cycles.motion_blur_position = 'START'
    assert bake.shutter_offsets(scene) == pytest.approx([0.0625, 0.1875, 0.3125, 0.4375])
    scene.cycles.motion_blur_position = 'END'
    assert bake.shutter_offsets(scene) == pytest.approx([-0.4375, -0.3125, -0.1875, -0.0625])
    scene.airlight.motion_samples = 1
    assert bake.shutter_offsets(scene) == []


@pytest.mark.parametrize("position", ['CENTER', 'START'])
def test02_shutter_samples_cover_the_pixels_as_cycles_motion_blur(tmp_path, position):
    scene = _moving_pole_scene(tmp_path, position)
    scene.airlight.enabled = False
    scene.render.filepath = str(tmp_path / "cycles.exr")
    bpy.ops.render.render(write_still=True)
    alpha = read_exr(str(tmp_path / "cycles.exr"))[0][..., 3].astype(np.float64)
    scene.airlight.motion_samples = 16
    depsgraph = bpy.context.evaluated_depsgraph_get()
    (_, settings, _), = bake.prepare_views(scene, depsgraph, str(tmp_path / "fog.exr"),
                                           evaluate_at=bake.frame_evaluator(scene))
    assert scene.frame_current == 2 and scene.frame_subframe == 0.0  # back at the frame
    samples = settings.pop(bake.SAMPLES)
    assert len(samples) == 16
    moving = hit_coverage(samples, settings)
    instant = hit_coverage([bake.prepare(scene, bpy.context.evaluated_depsgraph_get())[0]], settings)
    n_band, error, instant_error = coverage_errors(alpha, moving, instant)
    print(f"{position}: coverage vs Cycles' motion blur over {n_band} px: shutter samples {error:.3f}, "
          f"the frame's instant {instant_error:.3f}")
    assert n_band > 200
    assert error < 0.05, (error, instant_error)
    assert instant_error > 3 * error


def test03_background_render_bakes_the_shutter(tmp_path):
    """`blender -b -f 2` with motion blur: the frame's passes are the average of the shutter
    samples' bakes (each equal to a bake made here at that instant)."""
    scene = _moving_pole_scene(tmp_path)
    scene.airlight.motion_samples = 2
    scene.cycles.samples = 1
    bpy.ops.airlight.setup_compositor()
    blend = str(tmp_path / "blur.blend")
    bpy.ops.wm.save_as_mainfile(filepath=blend)
    proc = run_blender(blend, "-o", str(tmp_path / "out_####"), "-f", "2")
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    assert "Motion blur" not in proc.stdout, proc.stdout[-2000:]
    airlight = []
    for offset in (-0.25, 0.25):
        scene.frame_set(1 if offset < 0 else 2, subframe=0.75 if offset < 0 else 0.25)
        path = str(tmp_path / f"at_{offset}.exr")
        description, settings = bake.prepare(scene, bpy.context.evaluated_depsgraph_get())
        bake.run(description, settings, path)
        airlight.append(exr_pass(path, "Airlight"))
    baked = exr_pass(str(tmp_path / "cache" / "fog_0002.exr"), "Airlight")
    np.testing.assert_allclose(baked, 0.5 * (airlight[0] + airlight[1]), rtol=1e-5, atol=1e-7)
    assert np.abs(airlight[0] - airlight[1]).max() > 1e-3  # the instants differ
