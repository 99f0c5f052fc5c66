"""A diffuse floor lit by a sun lamp through a fog layer: the add-on's surface composite vs Cycles.

    tools/blender.sh -b --python tests/blender/run_tests.py -- tests/blender/test_cycles_sun_surface.py -s

Reference: Cycles with the fog as a homogeneous Volume Scatter slab (sigma_t = 0.3 /m,
albedo 1, isotropic) whose top is at FOG_TOP = 4 m (sides and bottom 1000 m away, as
test_cycles_sun.py), a grey Lambert floor (0.8) at z = 0 inside it, a sun of angle 0
shining down at 37 deg from the vertical, black world, diffuse_bounces = 1,
volume_bounces = 0: the floor receives the sun through the layer (e^{-sigma top / mu_s})
plus the sunlight the fog scattered once towards it (the glow, sunlight_glow.h), and the
camera, inside the layer, sees the floor through the fog plus the airlight. 64x48, 1024
samples, two seeds (their difference is the Monte Carlo noise).

Ours, through the add-on as a user runs it: the same scene WITHOUT the slab, scene.airlight on
(density 0.3, Fog Top 4 m), bpy.ops.airlight.bake, then a Cycles render with compositing:
(Combined + Combined_fog_<sun> (att - 1) + DiffCol x glow) x T + A. Without the glow term
(attenuation only) it must be clearly worse, or the test shows nothing.

Figures go to out/test_artifacts/cycles_sun_surface/summary.json and stdout.
"""

import os
import sys

import numpy as np
import pytest

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(HERE))
sys.path.insert(0, HERE)
import cycles_scenes as cs  # noqa: E402

ARTIFACTS = os.path.join(REPO, "out", "test_artifacts", "cycles_sun_surface")
SEEDS = (1, 2)
SIGMA_T = 0.3
FOG_TOP = 4.0
FLOOR_ALBEDO = 0.8
SUN_STRENGTH = 3.0
SUN_DIR = np.array([0.2, 0.6, -0.8]) / np.linalg.norm([0.2, 0.6, -0.8])
SCENE = dict(width=64, height=48, samples=1024, sigma_t=SIGMA_T, camera_location=(0.0, -6.0, 2.0),
             camera_pitch_deg=-35.0, floor_x=(-400.0, 400.0), floor_y=(-400.0, 400.0), clip_start=0.1,
             clip_end=1.0e5)
NOFOG_SAMPLES = 64
SUMMARY = cs.Summary(ARTIFACTS, "cycles_sun_surface")


def _build(slab, diffuse_bounces):
    import bpy
    desc = cs.FogScene(**{**SCENE, "fog": False})
    scene = cs.build(desc)
    cs.diffuse_floor(scene, FLOOR_ALBEDO, diffuse_bounces)
    if slab:
        cs.add_fog_slab(scene, FOG_TOP, SIGMA_T)
    cs.make_sun_lamp(scene.objects["RefLight"], SUN_DIR, SUN_STRENGTH)
    bpy.context.view_layer.update()
    return scene, desc


def _composite():
    """Render WITHOUT the slab, composited by the add-on's nodes; returns (H, W) red channel."""
    import bpy
    scene, desc = _build(slab=False, diffuse_bounces=0)
    st = scene.airlight
    st.density = SIGMA_T
    st.color = (1.0, 1.0, 1.0)
    st.use_fog_top = True
    st.fog_top = FOG_TOP
    st.model = 'SUN05'
    st.threads = 2
    st.cache_dir = os.path.join(ARTIFACTS, "cache")
    st.surface_shading = True
    st.auto_composite = True
    st.enabled = True
    assert bpy.ops.airlight.bake('EXEC_DEFAULT') == {'FINISHED'}
    scene.render.use_compositing = True
    scene.cycles.samples = NOFOG_SAMPLES
    path = os.path.join(ARTIFACTS, "composite.exr")
    cs.render(scene, path, seed=SEEDS[0])
    image = cs.read_exr_rgb(path)[..., 0].astype(np.float64)
    groups = [lg.name for lg in bpy.context.view_layer.lightgroups]
    st.enabled = False
    return image, groups


@pytest.fixture(scope="module")
def renders():
    cs.addon_ready()
    scene, desc = _build(slab=True, diffuse_bounces=1)
    images, seconds = cs.render_seeds(scene, ARTIFACTS, "cycles", SEEDS)
    cycles = [image[..., 0] for image in images]
    surface, groups = _composite()
    SUMMARY.report("cycles", samples=desc.samples, seconds=sum(seconds))
    return dict(cycles=cycles, ref=0.5 * (cycles[0] + cycles[1]), surface=surface, groups=groups)


def test01_sun_light_group(renders):
    assert renders["groups"] == ["fog_RefLight"], renders["groups"]


def test02_sun_surface_composite_matches_cycles(renders):
    """Floor blocks (8x8 means) and the floor-wide total match Cycles to noise + 1 %; the
    composite without the sun's glow term is clearly off."""
    ref, surface = renders["ref"], renders["surface"]
    c1, c2 = renders["cycles"]
    bref = cs.block_means(ref)
    block_noise = np.abs(cs.block_means(c1) - cs.block_means(c2)) / (cs.block_means(c1) + cs.block_means(c2))
    bmean = float(np.mean(np.abs(cs.block_means(surface) - bref) / bref))
    bias = float(surface.sum() / ref.sum() - 1.0)
    nbias = float(abs(c1.sum() - c2.sum()) / (c1.sum() + c2.sum()))
    from conftest import exr_pass
    baked = os.path.join(ARTIFACTS, "cache", "fog_0001.exr")
    glow = exr_pass(baked, "SurfaceGlow")[..., 0]
    glow_term = FLOOR_ALBEDO * glow * exr_pass(baked, "Transmittance")[..., 0]
    no_glow = surface - glow_term
    gbmean = float(np.mean(np.abs(cs.block_means(no_glow) - bref) / bref))
    gbias = float(no_glow.sum() / ref.sum() - 1.0)
    SUMMARY.report("blocks_8x8", surface_mean=bmean, no_glow_mean=gbmean, cycles_noise_mean=float(block_noise.mean()))
    SUMMARY.report("floor_total", surface_bias=bias, no_glow_bias=gbias, cycles_noise=nbias)
    assert np.all(np.isfinite(glow)) and glow.max() > 0.0
    assert abs(bias) < 0.01 + 2.0 * nbias, (bias, nbias)
    assert bmean < 0.01 + 2.0 * float(block_noise.mean()), (bmean, float(block_noise.mean()))
    assert gbmean > 3.0 * bmean, (gbmean, bmean)
