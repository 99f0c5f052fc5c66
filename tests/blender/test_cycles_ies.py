"""A point or spot light's IES profile in the fog against Cycles (light nodes: an IES Texture's Fac
into the Emission Strength), through the add-on's export (ies.py: the profile averaged about
the lamp's axis, fitted with Legendre polynomials, baked in closed form).

    tools/blender.sh -b --python tests/blender/run_tests.py -- tests/blender/test_cycles_ies.py -s

Scene: cycles_scenes' reference (homogeneous fog sigma_t = 0.15 /m, a black floor, one 1000 W
point light, 96 x 72, volume bounces 0), the lamp pointing down (its -Z) with an IES profile
written here: a smooth one brighter downwards, and a downlight that is dark above the
horizontal; and a spot light (100 deg, blend 0.3) with a batwing profile, brightest 40 deg off
its axis, which Cycles multiplies into the spot's cone. Two seeds at 256 samples; the bake is compared with Cycles over the fog pixels.
Then a missing file and a malformed one: the light bakes without its profile, and says so.
Figures: out/test_artifacts/cycles_ies/summary.json.
"""
import math
import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(HERE))
sys.path.insert(0, HERE)
import cycles_scenes as cs  # noqa: E402

ARTIFACTS = os.path.join(REPO, "out", "test_artifacts", "cycles_ies")
SUMMARY = cs.Summary(ARTIFACTS, "[cycles_ies]", digits=4)


def ies_text(polar, candela, multiplier=1.0):
    lines = ["IESNA:LM-63-2002", "[TEST] airlight", "TILT=NONE",
             f"1 -1 {multiplier:g} {len(polar)} 1 1 2 0 0 0", "1.0 1.0 100",
             " ".join(f"{v:g}" for v in polar), "0", " ".join(f"{c:.6g}" for c in candela)]
    return "\n".join(lines) + "\n"


POLAR = np.arange(0.0, 180.1, 5.0)
SMOOTH = ies_text(POLAR, 200.0 + 1800.0 * ((1.0 + np.cos(np.radians(POLAR))) / 2.0) ** 3)
DOWN = np.arange(0.0, 90.1, 2.5)
DOWNLIGHT = ies_text(DOWN, 1500.0 * np.cos(np.radians(DOWN)) ** 2, multiplier=1.5)
BATWING = ies_text(POLAR, 300.0 + 1700.0 * np.sin(np.radians(np.minimum(POLAR, 90.0)) * 2.25) ** 2)
SPOT_CONE = (math.radians(100.0), 0.3)


def _lamp_with_ies(scene, text=None, filepath=None):
    import bpy
    lamp = next(o for o in scene.objects if o.type == 'LIGHT')
    lamp.rotation_euler = (0.0, 0.0, 0.0)  # -Z: straight down
    light = lamp.data
    light.use_nodes = True
    tree = light.node_tree
    emission = next(n for n in tree.nodes if n.type == 'EMISSION')
    node = next((n for n in tree.nodes if n.type == 'TEX_IES'), None) or tree.nodes.new("ShaderNodeTexIES")
    tree.links.new(node.outputs["Fac"], emission.inputs["Strength"])
    if filepath is not None:
        node.mode = 'EXTERNAL'
        node.filepath = filepath
    else:
        node.mode = 'INTERNAL'
        block = bpy.data.texts.get("airlight_test.ies") or bpy.data.texts.new("airlight_test.ies")
        block.clear()
        block.write(text)
        node.ies = block
    bpy.context.view_layer.update()
    return lamp


def _fog_mask(scene, desc, C):
    inputs = cs.bake_inputs(scene)
    o, d = cs.camera_rays(inputs["cam_to_world"], inputs["projection"], desc.width, desc.height, from_eye=True)
    floor = cs.silhouette_mask(cs.floor_depth(o, d, desc), radius=2)
    return ~floor & (C > 0.0)


def _bake(scene):
    import bpy
    from airlight import native, scene_export
    exported = scene_export.export_scene(scene, bpy.context.evaluated_depsgraph_get())
    A = native.get().bake(**exported, aa_samples=4, threads=2)["airlight"][..., 0].astype(np.float64)
    return A, exported


def _check(name, text, margin, cone=None):
    """_cone_ (spot_size, spot_blend): the lamp is a spot light of that cone."""
    import bpy
    from airlight import ies
    desc = cs.FogScene(width=96, height=72, samples=256)
    scene = cs.build(desc)
    scene.render.engine = 'CYCLES'
    scene.airlight.density = desc.sigma_t
    lamp = _lamp_with_ies(scene, text)
    if cone is not None:
        lamp.data.type = 'SPOT'
        lamp.data.spot_size, lamp.data.spot_blend = cone
        bpy.context.view_layer.update()
    (c1, c2), _ = cs.render_seeds(scene, ARTIFACTS, name, (1, 2))
    C = 0.5 * (c1 + c2)[..., 0]
    noise = cs.seed_noise(c1, c2)
    A, exported = _bake(scene)
    assert "spot_profiles" in exported and len(exported["light_positions"]) == 0, sorted(exported)
    fit = ies.fit_text(text, scene.airlight.accuracy / 100.0, ies.light_cone(lamp.data))
    if cone is not None:
        assert exported["spot_profile_in_cone"].tolist() == [1.0], exported.get("spot_profile_in_cone")
    mask = _fog_mask(scene, desc, C)
    if cone is not None:
        # The cone's edge (2 pixels either side) is the spot's own, without its profile
        # (test_cycles_spot.py): measured here over the light inside it.
        edge = cs.silhouette_mask(np.where(C > 0.02 * np.median(C[mask]), 1.0, np.inf), radius=2)
        mask &= ~edge
    mean, p99 = cs.rel_stats(A, C, mask)
    lit = mask & (C > 0.5 * np.median(C[mask]))   # the fog the lamp lights (a downlight leaves the rest dark)
    lit_mean, lit_p99 = cs.rel_stats(A, C, lit)
    flux = float(np.abs(A[mask] - C[mask]).sum() / C[mask].sum())
    lamp.data.use_nodes = False  # the same lamp without its profile: what the profile changes
    bpy.context.view_layer.update()
    A0, _ = _bake(scene)
    plain_mean, _ = cs.rel_stats(A0 * fit.mean / 1.0, C, mask)  # an even lamp (spot) of the profile's mean
    SUMMARY.report(name, mean=mean, p99=p99, lit_mean=lit_mean, lit_p99=lit_p99, flux=flux, even_lamp=plain_mean,
                   noise=float(noise[mask].mean()), lit_noise=float(noise[lit].mean()), fit_degree=fit.degree,
                   fit_mean_error=fit.mean_error, fit_max_error=fit.max_error, pixels=int(mask.sum()),
                   lit_pixels=int(lit.sum()))
    assert mask.sum() > (0.05 if cone is not None else 0.5) * mask.size and lit.sum() > 0.2 * mask.sum()
    assert plain_mean > 0.1, plain_mean            # the profile matters here ...
    # ... and the bake has it: over the lit fog within Cycles' noise and the margin, and the
    # image's light (the absolute differences summed over the fog) too.
    assert lit_mean < 3.0 * float(noise[lit].mean()) + margin, (lit_mean, noise[lit].mean())
    assert flux < 3.0 * float(noise[mask].mean()) + margin + 0.015, flux  # (+ the light image's own pixels)
    return mean


def test01_smooth_profile_matches_cycles():
    assert _check("smooth", SMOOTH, 0.01) < 0.01  # every fog pixel too


def test02_downlight_matches_cycles():
    # The profile is dark past 90 deg: fitted over the lit half only (degree 2) and cut there.
    # Measured: 2.0 % mean over the fog it lights (p99 47 %, in the band level with the lamp,
    # where Cycles gives ~8x the file's cos^2 at grazing angles), 2.5 % of the image's light;
    # the profile ignored is off by orders of magnitude. (Fitted over the whole sphere, degree
    # 7, its residual glow above the horizon made that 5.9 %, p99 67 %.)
    _check("downlight", DOWNLIGHT, 0.03)


def test03_missing_or_malformed_profile_bakes_without_it_and_says_so(tmp_path):
    import bpy
    from airlight import bake, scene_export, ui
    desc = cs.FogScene(width=32, height=24, samples=1)
    scene = cs.build(desc)
    scene.render.engine = 'CYCLES'
    scene.airlight.density = desc.sigma_t
    for kind, lamp in (("missing", lambda: _lamp_with_ies(scene, filepath=str(tmp_path / "nowhere.ies"))),
                       ("malformed", lambda: _lamp_with_ies(scene, "IESNA:LM-63-2002\nTILT=NONE\n1 -1 1 x\n"))):
        light = lamp()
        exported = scene_export.export_scene(scene, bpy.context.evaluated_depsgraph_get())
        assert "spot_profiles" not in exported and len(exported["light_positions"]) == 1, kind
        description, settings = bake.prepare(scene, bpy.context.evaluated_depsgraph_get())
        notes = settings.get(bake.LIGHT_NOTES, [])
        assert notes and "WARNING" in notes[0] and "without its profile" in notes[0], (kind, notes)
        stats, _ = bake.run(description, settings, str(tmp_path / f"{kind}.exr"))
        assert stats[bake.LIGHT_NOTES] == notes
        warn, lines = ui.light_ies_note(light.data, scene)
        assert warn and "without its profile" in lines[-1], (kind, lines)
        SUMMARY.report(kind, note=notes[0])
    # A spot without its (unreadable) profile keeps its cone; a profile on an area light is
    # refused with a message.
    light.data.type = 'SPOT'
    bpy.context.view_layer.update()
    exported = scene_export.export_scene(scene, bpy.context.evaluated_depsgraph_get())
    assert "spot_profiles" not in exported and len(exported["spot_positions"]) == 1
    description, settings = bake.prepare(scene, bpy.context.evaluated_depsgraph_get())
    assert "spot cone alone" in settings[bake.LIGHT_NOTES][0], settings[bake.LIGHT_NOTES]
    light.data.type = 'AREA'
    bpy.context.view_layer.update()
    try:
        scene_export.export_scene(scene, bpy.context.evaluated_depsgraph_get())
        raise AssertionError("exported")
    except scene_export.ExportError as ex:
        assert "IES Texture on an area light" in str(ex), str(ex)


def test04_an_ies_light_is_a_spot_row_after_the_spots_everywhere(tmp_path):
    import bpy
    from airlight import bake, scene_export, surface
    desc = cs.FogScene(width=32, height=24, samples=1)
    scene = cs.build(desc)
    scene.render.engine = 'CYCLES'
    scene.airlight.density = desc.sigma_t
    lamp = _lamp_with_ies(scene, SMOOTH)
    for name, kind, where in (("Other", 'POINT', (2.0, 4.0, 2.0)), ("Spot", 'SPOT', (-2.0, 4.0, 3.0))):
        obj = bpy.data.objects.new(name, bpy.data.lights.new(name, kind))
        obj.location = where
        scene.collection.objects.link(obj)
    bpy.context.view_layer.update()
    depsgraph = bpy.context.evaluated_depsgraph_get()
    names = {}
    exported, _ = scene_export.export(scene, depsgraph, light_names=names)
    assert names["points"] == ["Other"] and names["spots"] == ["Spot", lamp.name], names
    assert len(exported["light_positions"]) == 1 and len(exported["spot_positions"]) == 2
    assert not exported["spot_profiles"][0].any() and exported["spot_profiles"][1].any()
    order = [obj.name for obj, _ in surface.fogged_lights(depsgraph)]
    assert order == ["Other", "Spot", lamp.name], order
    # Per-light passes: one per light, summing to the total.
    scene.airlight.light_passes = True
    description, settings = bake.prepare(scene, depsgraph)
    stats, _ = bake.run(description, settings, str(tmp_path / "passes.exr"))
    from airlight import native
    total = native.get().bake(**description, **bake.native_settings(settings))["airlight"]
    parts = [bake._one_light(description, settings[bake.LIGHT_PASSES], n) for n in ("Other", "Spot", lamp.name)]
    summed = sum(native.get().bake(**p, **bake.native_settings(settings))["airlight"] for p in parts)
    np.testing.assert_allclose(summed, total, rtol=1e-4, atol=1e-7)


def test05_spot_with_a_profile_matches_cycles():
    # Measured inside the cone: 0.49 % mean (noise 0.33 %), p99 2.1 %, fit degree 4; the same spot without
    # the profile's shape (an even spot of its mean) 17 %.
    assert _check("spot", BATWING, 0.01, cone=SPOT_CONE) < 0.01
