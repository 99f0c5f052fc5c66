"""The fog's glow on a floor in a wall's shadow vs Cycles: what the unshadowed glow costs.

    tools/blender.sh -b --python tests/blender/run_tests.py -- tests/blender/test_cycles_surface_shadow.py -s

test_cycles_surface.py's scene (a grey Lambert floor under a 1000 W point light through
sigma_t = 0.3 /m fog, diffuse_bounces 1, volume_bounces 0, 1024 samples, two seeds) with the
light moved to (-0.5, 0, 1.5) and a black wall 1 m high in the plane x = 0, seen edge-on by
the camera: the floor at 0 < x < 2.5 m lies in the wall's shadow. There Cycles' floor gets
no direct light, only the glow of the fog that the light reaches and the floor point sees
(not the fog behind the wall). Sun 2005's glow (eq. 13) integrates the whole fog around the
floor point as if lit; with Volumetric Shadows the bake scales it by its lit share
(native/bake/glow_shadow.h). Ours: the add-on's bake with surface shading, composited over a
render without fog, Volumetric Shadows on and off.

Measured here (floor totals against the mean of the two seeds; Cycles' noise 0.05 %):
  shadows on: lit floor -0.86 %, shadowed floor +0.91 % (the glow is 32 % of its light);
  shadows off: lit floor +1.65 %, shadowed floor +66.7 %; shadows on with the glow left
  unshadowed (the airlight shadowed, the glow not): shadowed floor +46.5 %.
"""

import os
import sys

import numpy as np
import pytest

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(HERE))
sys.path.insert(0, HERE)
import cycles_scenes as cs  # noqa: E402

ARTIFACTS = os.path.join(REPO, "out", "test_artifacts", "cycles_surface_shadow")
SEEDS = (1, 2)
SIGMA_T = 0.3
FLOOR_ALBEDO = 0.8
LIGHT = (-0.5, 0.0, 1.5)
WALL_TOP = 1.0
SCENE = dict(width=64, height=48, samples=1024, sigma_t=SIGMA_T, light_power=1000.0,
             light_location=LIGHT, camera_location=(0.0, -6.0, 4.0),
             camera_pitch_deg=-45.0, floor_x=(-40.0, 40.0), floor_y=(-40.0, 40.0),
             clip_start=0.1, clip_end=1000.0)
NOFOG_SAMPLES = 64
SUMMARY = cs.Summary(ARTIFACTS, "cycles_surface_shadow")
# The floor x in (0, SHADOW_END) is in the wall's shadow (the light's height over the wall's).
SHADOW_END = LIGHT[0] + (0.0 - LIGHT[0]) * LIGHT[2] / (LIGHT[2] - WALL_TOP)


def _build(fog, diffuse_bounces):
    import bpy
    desc = cs.FogScene(**{**SCENE, "fog": fog})
    scene = cs.build(desc)
    cs.diffuse_floor(scene, FLOOR_ALBEDO, diffuse_bounces)
    mesh = bpy.data.meshes.new("Wall")
    mesh.from_pydata([(0.0, -40.0, 0.0), (0.0, 40.0, 0.0), (0.0, 40.0, WALL_TOP), (0.0, -40.0, WALL_TOP)], [],
                     [(0, 1, 2, 3)])
    mesh.materials.append(cs._black_material())
    scene.collection.objects.link(bpy.data.objects.new("Wall", mesh))
    bpy.context.view_layer.update()
    return scene, desc


def _composite(shadows):
    scene, desc = _build(fog=False, diffuse_bounces=0)
    image = cs.addon_composite(scene, SIGMA_T, os.path.join(ARTIFACTS, f"cache_{shadows}"),
                               os.path.join(ARTIFACTS, f"composite_{shadows}.exr"), NOFOG_SAMPLES, SEEDS[0],
                               surface_shading=True, volumetric_shadows=shadows)
    return image, scene


@pytest.fixture(scope="module")
def renders():
    cs.addon_ready()
    scene, desc = _build(fog=True, diffuse_bounces=1)
    images, seconds = cs.render_seeds(scene, ARTIFACTS, "cycles_fog", SEEDS)
    c1, c2 = (image[..., 0] for image in images)
    inputs = cs.bake_inputs(scene)
    o, d = cs.camera_rays(inputs["cam_to_world"], inputs["projection"], desc.width, desc.height)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = -o[..., 2] / d[..., 2]
    x = o[..., 0] + t * d[..., 0]
    composite, _ = _composite(True)
    unshadowed, _ = _composite(False)
    return dict(c1=c1, c2=c2, ref=0.5 * (c1 + c2), x=x, composite=composite, unshadowed=unshadowed,
                seconds=sum(seconds))


def _region_bias(image, ref, region):
    return float(image[region].sum() / ref[region].sum() - 1.0)


def test01_shadowed_floor_glow_against_cycles(renders):
    """The composite matches Cycles over the lit and the shadowed floor; the unshadowed glow
    (Volumetric Shadows off) overstates the shadowed floor."""
    from conftest import exr_pass
    ref, x, composite = renders["ref"], renders["x"], renders["composite"]
    c1, c2 = renders["c1"], renders["c2"]
    shadowed = (x > 0.2) & (x < SHADOW_END - 0.2)
    lit = x < -0.2
    assert shadowed.sum() > 100 and lit.sum() > 100
    noise = {name: abs(c1[m].sum() - c2[m].sum()) / (c1[m].sum() + c2[m].sum())
             for name, m in (("shadowed", shadowed), ("lit", lit))}
    baked = os.path.join(ARTIFACTS, "cache_True", "fog_0001.exr")
    glow = FLOOR_ALBEDO * exr_pass(baked, "SurfaceGlow")[..., 0] * exr_pass(baked, "Transmittance")[..., 0]
    lit_bias = _region_bias(composite, ref, lit)
    shadow_bias = _region_bias(composite, ref, shadowed)
    glow_share = float(glow[shadowed].sum() / composite[shadowed].sum())
    off_lit, off_shadowed = _region_bias(renders["unshadowed"], ref, lit), _region_bias(renders["unshadowed"], ref,
                                                                                            shadowed)
    SUMMARY.report("floor", lit_bias=lit_bias, shadowed_bias=shadow_bias, cycles_noise_lit=noise["lit"],
                   cycles_noise_shadowed=noise["shadowed"], glow_share_shadowed=glow_share,
                   unshadowed_glow_lit_bias=off_lit, unshadowed_glow_shadowed_bias=off_shadowed,
                   shadowed_pixels=int(shadowed.sum()), cycles_seconds=renders["seconds"])
    assert glow_share > 0.2, glow_share   # the glow is a visible part of the shadowed floor
    assert abs(lit_bias) < 0.02 + 2 * noise["lit"], lit_bias
    assert abs(shadow_bias) < 0.03 + 2 * noise["shadowed"], shadow_bias
    # The unshadowed glow overstates the shadowed floor (it is all that lights it there).
    assert off_shadowed > 0.2, off_shadowed
