"""Surface shading through fog vs Cycles: a diffuse floor lit by a point light through fog.

    tools/blender.sh -b --python tests/blender/run_tests.py -- tests/blender/test_cycles_surface.py -s

Reference: Cycles with the fog as a homogeneous world volume (sigma_t = 0.3 /m, albedo 1,
isotropic), diffuse_bounces = 1, volume_bounces = 0 (the floor receives the light's direct
light through the fog plus the light the fog scattered once: Sun 2005 eq. 13), a grey
Lambert floor (0.8), a 1000 W point light of radius 0 out of view 1.5 m above the floor, a
black world, 64x48, 1024 samples, two seeds (their difference is the Monte Carlo noise).

Ours, through the add-on as a user runs it: the same scene WITHOUT the world volume,
scene.airlight on (density 0.3), bpy.ops.airlight.bake (sets up light groups, the DiffCol
pass and the compositor's "Airlight Fog" frame), then a Cycles render with compositing (the
render_pre handler bakes again): final = (Combined + Combined_fog_<light> (att - 1) +
DiffCol x glow) x T + A. The same with surface shading off is the old composite
render x T + A, which must be clearly worse, or the test shows nothing; so must the
composite without the glow term (attenuation only).

Figures (mean / p99 relative difference over floor pixels) go to
out/test_artifacts/cycles_surface/summary.json and stdout.
"""

import os
import sys
import time

import numpy as np
import pytest

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(HERE))
sys.path.insert(0, HERE)
import cycles_scenes as cs  # noqa: E402

ARTIFACTS = os.path.join(REPO, "out", "test_artifacts", "cycles_surface")
SEEDS = (1, 2)
SIGMA_T = 0.3
FLOOR_ALBEDO = 0.8
SCENE = dict(width=64, height=48, samples=1024, sigma_t=SIGMA_T, light_power=1000.0,
             light_location=(0.5, 0.0, 1.5), camera_location=(0.0, -6.0, 4.0),
             camera_pitch_deg=-45.0, floor_x=(-40.0, 40.0), floor_y=(-40.0, 40.0),
             clip_start=0.1, clip_end=1000.0)
NOFOG_SAMPLES = 64
SUMMARY = cs.Summary(ARTIFACTS, "cycles_surface")


def _build(fog, diffuse_bounces):
    import bpy
    desc = cs.FogScene(**{**SCENE, "fog": fog})
    scene = cs.build(desc)
    cs.diffuse_floor(scene, FLOOR_ALBEDO, diffuse_bounces)
    bpy.context.view_layer.update()
    return scene, desc


def _composite(surface_shading, name):
    """Render WITHOUT fog, composited by the add-on's nodes; returns (H, W) red channel."""
    import bpy
    scene, desc = _build(fog=False, diffuse_bounces=0)
    image = cs.addon_composite(scene, SIGMA_T, os.path.join(ARTIFACTS, f"cache_{name}"),
                               os.path.join(ARTIFACTS, f"composite_{name}.exr"), NOFOG_SAMPLES, SEEDS[0],
                               surface_shading=surface_shading)
    groups = ([lg.name for lg in bpy.context.view_layer.lightgroups], scene.objects["RefLight"].lightgroup,
              bpy.context.view_layer.use_pass_diffuse_color)
    return image, groups, scene


@pytest.fixture(scope="module")
def renders():
    cs.addon_ready()
    scene, desc = _build(fog=True, diffuse_bounces=1)
    images, seconds = cs.render_seeds(scene, ARTIFACTS, "cycles_fog", SEEDS)
    cycles = [image[..., 0] for image in images]
    seconds = sum(seconds)
    ref = 0.5 * (cycles[0] + cycles[1])
    noise = cs.seed_noise(*cycles)
    inputs = cs.bake_inputs(scene)
    W, H = desc.width, desc.height
    o, d = cs.camera_rays(inputs["cam_to_world"], inputs["projection"], W, H)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = -o[..., 2] / d[..., 2]
    floor = np.isfinite(t) & (t > 0)
    t0 = time.perf_counter()
    surface, groups, _ = _composite(True, "surface")
    plain, _, _ = _composite(False, "plain")
    SUMMARY.report("cycles", samples=desc.samples, seconds=seconds, floor_pixels=int(floor.sum()),
                   noise_mean=float(noise[floor].mean()), noise_p99=float(np.percentile(noise[floor], 99)))
    return dict(ref=ref, cycles=cycles, noise=noise, floor=floor, surface=surface, plain=plain, groups=groups,
                composite_seconds=time.perf_counter() - t0)


def test01_light_group_and_passes_enabled(renders):
    """The bake enabled one light group for the fogged light and the DiffCol pass."""
    view_layer_groups, light_group, diffcol = renders["groups"]
    assert view_layer_groups == ["fog_RefLight"], view_layer_groups
    assert light_group == "fog_RefLight"
    assert diffcol


def test02_surface_composite_matches_cycles(renders):
    """(Combined + LG (att - 1) + DiffCol glow) T + A equals Cycles with fog to noise + model."""
    floor, ref, noise = renders["floor"], renders["ref"], renders["noise"]
    mean, p99 = cs.rel_stats(renders["surface"], ref, floor)
    pmean, pp99 = cs.rel_stats(renders["plain"], ref, floor)
    SUMMARY.report("surface_vs_cycles", mean=mean, p99=p99)
    SUMMARY.report("plain_vs_cycles", mean=pmean, p99=pp99)
    # Per-pixel figures are dominated by Cycles' noise (diffuse bounce + volume scattering);
    # 8x8-pixel block means and the floor-wide ratio average it away and show the bias.
    blocks = cs.block_means
    assert floor.all()  # the whole frame is floor (so blocks are floor only)
    c1, c2 = renders["cycles"]
    block_noise = np.abs(blocks(c1) - blocks(c2)) / (blocks(c1) + blocks(c2))
    bref = blocks(ref)
    bmean = float(np.mean(np.abs(blocks(renders["surface"]) - bref) / bref))
    bmax = float(np.max(np.abs(blocks(renders["surface"]) - bref) / bref))
    pbmean = float(np.mean(np.abs(blocks(renders["plain"]) - bref) / bref))
    bias = float(renders["surface"].sum() / ref.sum() - 1.0)
    pbias = float(renders["plain"].sum() / ref.sum() - 1.0)
    nbias = float(abs(c1.sum() - c2.sum()) / (c1.sum() + c2.sum()))
    SUMMARY.report("blocks_8x8", surface_mean=bmean, surface_max=bmax, plain_mean=pbmean,
                   cycles_noise_mean=float(block_noise.mean()), cycles_noise_max=float(block_noise.max()))
    SUMMARY.report("floor_total", surface_bias=bias, plain_bias=pbias, cycles_noise=nbias)
    assert abs(bias) < 0.01 + 2.0 * nbias, (bias, nbias)
    assert bmean < 0.01 + 2.0 * float(block_noise.mean()), (bmean, float(block_noise.mean()))
    # Without the glow term (Sun 2005 eq. 17's G0 part): the surface composite minus
    # DiffCol x SurfaceGlow x T, from the baked passes (the floor's DiffCol is FLOOR_ALBEDO).
    from conftest import exr_pass
    baked = os.path.join(ARTIFACTS, "cache_surface", "fog_0001.exr")
    glow_term = FLOOR_ALBEDO * exr_pass(baked, "SurfaceGlow")[..., 0] * exr_pass(baked, "Transmittance")[..., 0]
    no_glow = renders["surface"] - glow_term
    gbias = float(no_glow.sum() / ref.sum() - 1.0)
    gbmean = float(np.mean(np.abs(blocks(no_glow) - bref) / bref))
    SUMMARY.report("attenuation_only", block_mean=gbmean, floor_bias=gbias)
    assert gbmean > 3.0 * bmean, (gbmean, bmean)
    nmean = float(noise[floor].mean())
    # The composite's own Monte Carlo noise (64 spp without fog) and the table error are
    # small; the bound is the Cycles noise plus 1 %.
    assert mean < nmean + 0.01, (mean, nmean)
    # The old composite (surfaces lit as if there were no fog) must be clearly worse.
    assert pmean > 5.0 * mean, (pmean, mean)
