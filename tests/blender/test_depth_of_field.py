"""Depth of field: the fog is baked from points over the lens aperture and averaged
(scene.airlight.lens_samples, scene_description.export_lens, bake._average), so that the fog
passes blur at out-of-focus silhouettes as the render does.

The reference is Cycles: two poles in front of an empty world, one in the focus plane and
one near the camera, rendered with depth of field; its alpha is each pixel's coverage by
the poles over the lens. The lens samples' cameras must give the same coverage (the
fraction of them whose centre ray hits a pole), and the in-focus pole must stay sharp."""

import bpy
import numpy as np
import pytest

from airlight import bake, native, render, scene_description, scene_export
from conftest import coverage_errors, exr_pass, hit_coverage, poles_scene, read_exr


def _poles_scene(tmp_path, fstop=0.4, focus=4.0, use_object=False):
    scene, _ = poles_scene(tmp_path, [((-0.25, 1.2, 1.0), (0.12, 0.12, 6.0)),  # near
                                      ((0.9, focus, 1.0), (0.3, 0.3, 6.0))], 256)  # in focus
    scene.cycles.filter_width = 0.01  # (a point filter: the bake's hit masks have none)
    dof = scene.camera.data.dof
    dof.use_dof = True
    dof.aperture_fstop = fstop
    if use_object:
        target = bpy.data.objects.new("Focus", None)
        target.location = (2.0, focus, 3.0)  # off axis: the distance along the view axis counts
        scene.collection.objects.link(target)
        dof.focus_object = target
        dof.focus_distance = 100.0  # ignored
    else:
        dof.focus_distance = focus
    return scene


def _coverage(scene, cameras):
    """hit_coverage of the scene's bake seen by each of _cameras_."""
    description, settings = bake.prepare(scene, bpy.context.evaluated_depsgraph_get())
    settings.pop(bake.LENS, None)
    return hit_coverage([dict(description, cam_to_world=c, projection=p) for c, p in cameras], settings)


@pytest.mark.parametrize("use_object", [False, True])
def test01_lens_samples_cover_the_pixels_as_cycles_thin_lens(tmp_path, use_object):
    scene = _poles_scene(tmp_path, use_object=use_object)
    scene.airlight.enabled = False
    scene.render.filepath = str(tmp_path / "cycles.exr")
    bpy.ops.render.render(write_still=True)
    alpha = read_exr(str(tmp_path / "cycles.exr"))[0][..., 3].astype(np.float64)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    description = scene_export.export_scene(scene, depsgraph)
    scene.airlight.lens_samples = 64
    cameras = scene_description.export_lens(scene, depsgraph, None, description["cam_to_world"],
                                       description["projection"])
    assert cameras is not None and len(cameras) == 64
    lens = _coverage(scene, cameras)
    pinhole = _coverage(scene, [(description["cam_to_world"], description["projection"])])
    # The partly covered pixels: the blurred band of the near pole and the sharp edges of
    # the far one.
    n_band, error, pinhole_error = coverage_errors(alpha, lens, pinhole)
    print(f"focus object {use_object}: coverage vs Cycles' thin lens over {n_band} px: lens samples "
          f"{error:.3f}, one pinhole {pinhole_error:.3f}")
    assert n_band > 100
    assert error < 0.05, (error, pinhole_error)
    assert pinhole_error > 3 * error
    # The far pole is in the focus plane: its edges stay as sharp as the pinhole's.
    far_cols = slice(40, 64)
    assert np.abs(lens - pinhole)[:, far_cols].max() < 0.2


def test02_lens_average_rules():
    """Airlight and the surface passes: the mean of all samples; transmittance: the mean of
    the samples that hit (the world seen through infinite fog has T = 0)."""
    depth = [np.array([[1.0, np.inf]]), np.array([[np.inf, np.inf]])]
    A = [np.array([[[1.0] * 3, [2.0] * 3]]), np.array([[[3.0] * 3, [4.0] * 3]])]
    T = [np.array([[[0.5] * 3, [0.0] * 3]]), np.array([[[0.0] * 3, [0.0] * 3]])]
    E = [{"Surface_x": np.full((1, 2, 3), 2.0)}, {"Surface_x": np.full((1, 2, 3), 4.0)}]
    calls = []

    def bake_once(description, progress):
        k = len(calls)
        calls.append(description["cam_to_world"])
        if progress is not None:
            progress(1.0)
        return A[k], T[k], E[k], depth[k], {"samples": k}

    fractions = []
    airlight, transmittance, extra, stats = bake._average(
        bake_once, [{"cam_to_world": "c0"}, {"cam_to_world": "c1"}], fractions.append)
    assert calls == ["c0", "c1"] and fractions == [0.5, 1.0]
    np.testing.assert_allclose(airlight[0, :, 0], [2.0, 3.0])
    np.testing.assert_allclose(transmittance[0, :, 0], [0.5, 0.0])  # pixel 0: only sample 0 hits
    np.testing.assert_allclose(extra["Surface_x"], 3.0)
    assert stats["averaged_bakes"] == 2 and stats["samples"] == 0


def test03_bake_averages_the_lens_samples_and_the_panel_no_longer_warns(tmp_path):
    scene = _poles_scene(tmp_path)
    scene.airlight.lens_samples = 4
    depsgraph = bpy.context.evaluated_depsgraph_get()
    description, settings = bake.prepare(scene, depsgraph)
    assert len(settings[bake.LENS]) == 4
    path = str(tmp_path / "fog.exr")
    stats, _ = bake.run(description, settings, path)
    assert stats["averaged_bakes"] == 4
    # The same as averaging the four bakes by hand.
    plain = bake.native_settings(settings)
    lens = settings[bake.LENS]
    sums, count = 0.0, 0
    for cam_to_world, projection in lens:
        result = native.get().bake(**dict(description, cam_to_world=cam_to_world, projection=projection), **plain)
        sums = sums + result["airlight"]
        count += 1
    np.testing.assert_allclose(exr_pass(path, "Airlight"), sums / count, rtol=1e-5, atol=1e-7)
    assert render.DEPTH_OF_FIELD not in render.render_notes(scene)
    scene.airlight.lens_samples = 1
    assert bake.LENS not in bake.prepare(scene, depsgraph)[1]
    assert render.DEPTH_OF_FIELD in render.render_notes(scene)
