"""Gaussian (Fogshop) fog lit by a sun lamp, a spot light and a point light with
Henyey-Greenstein anisotropy (g = 0.5, Cycles' sign): the Airlight bake vs Cycles on
test_cycles_gaussians.py's medium (a 7 m box whose Volume Scatter density is the sum of the
same Gaussians, step rate 0.1); the sun (angle 0) shines towards the camera (forward
scattering), the spot (1 rad, blend 0.3) sits at the point light's place aimed at the
Gaussians. Measured (2 x 128 spp): exact bake vs Cycles flux bias sun -0.12 %, spot
-0.59 %, point +0.82 %, mean relative difference 6.3 / 4.0 / 1.5 % against a noise of
5.9 / 3.0 / 1.3 %.

    tools/blender.sh -b --python tests/blender/run_tests.py -- tests/blender/test_cycles_gaussians_sun.py -s

The bake's 'quadrature' model (eq. 2 with exact Gaussian optical depths, the sun's half-line
through the Gaussians, the HG phase: airlight.h GaussianRefLight) must equal Cycles to Monte
Carlo noise (the spot's p99 is held loosely: its cone-edge pixels); the Fogshop path ('biri06' model: f0 = E p(cos theta) at b_i^r, the Gaussian's
own light-side depth by the erfc half-line) is measured against both and reported (these
Gaussians are optically thick, c sqrt(pi) / a up to 0.5; at a tenth of the density, the
thin regime, against the exact bake only). Figures:
out/test_artifacts/cycles_gaussians_sun/summary.json.
"""

import os
import sys

import numpy as np
import pytest

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(HERE))
sys.path.insert(0, HERE)
import cycles_scenes as cs  # noqa: E402

ARTIFACTS = os.path.join(REPO, "out", "test_artifacts", "cycles_gaussians_sun")
SEEDS = (1, 2)
SAMPLES = 128
G = 0.5
SUN_STRENGTH = 3.0
SUN_COLOR = (1.0, 0.8, 0.6)
SUN_DIR = np.array([0.2, -0.6, -0.8]) / np.linalg.norm([0.2, -0.6, -0.8])  # propagation
SUMMARY = cs.Summary(ARTIFACTS, "[cycles_gaussians_sun]", digits=4)  # (keys carry the light: "sun/...")


SPOT_POWER = 300.0
SPOT_SIZE = 1.0    # rad, full cone angle
SPOT_BLEND = 0.3


@pytest.fixture(scope="module", params=["sun", "spot", "point"])
def refs(request):
    kind = request.param
    import bpy
    from mathutils import Vector
    from airlight import native
    _desc, scene = cs.gaussian_scene(SAMPLES)
    # (this scene's box and lamp: an earlier fixture's data may hold the plain names)
    box = next(ob for ob in scene.objects if ob.name.startswith("RefFogBox"))
    scatter = [n for n in box.data.materials[0].node_tree.nodes if n.type == 'VOLUME_SCATTER']
    assert len(scatter) == 1
    scatter[0].inputs["Anisotropy"].default_value = G
    light = next(ob for ob in scene.objects if ob.type == 'LIGHT')
    light.rotation_mode = 'QUATERNION'
    if kind == "sun":
        cs.make_sun_lamp(light, SUN_DIR, SUN_STRENGTH, SUN_COLOR)
    elif kind == "spot":  # a spot at the point light's place aimed at the Gaussians (soft edge)
        light.data.type = 'SPOT'
        light.data.energy = SPOT_POWER
        light.data.color = SUN_COLOR
        light.data.shadow_soft_size = 0.0
        light.data.spot_size = SPOT_SIZE
        light.data.spot_blend = SPOT_BLEND
        axis = np.array([0.0, 2.3, 1.6]) - np.array(light.location)
        light.rotation_quaternion = Vector((0.0, 0.0, -1.0)).rotation_difference(Vector(axis.tolist()))
    bpy.context.view_layer.update()
    renders, seconds = cs.render_seeds(scene, ARTIFACTS, f"cycles_{kind}", SEEDS)
    seconds = sum(seconds)
    module = native.get()
    inputs = cs.bake_inputs(scene)  # (no point lights now: the sun goes in apart)
    assert len(inputs["light_positions"]) == (kind == "point")
    lamp_dir = -np.array(light.matrix_world.col[2][:3])
    if kind == "sun":
        np.testing.assert_allclose(lamp_dir, SUN_DIR, atol=1e-6)
        lights = dict(sun_directions=SUN_DIR[None, :], sun_irradiances=SUN_STRENGTH * np.asarray(SUN_COLOR)[None, :])
    elif kind == "point":
        lights = {}
    else:
        lights = dict(spot_positions=np.array(light.matrix_world.translation)[None, :], spot_axes=lamp_dir[None, :],
                      spot_intensities=SPOT_POWER / (4.0 * np.pi) * np.asarray(SUN_COLOR)[None, :],
                      spot_size=np.array([SPOT_SIZE]), spot_blend=np.array([SPOT_BLEND]))
    common = dict(inputs, sigma_t=0.0, albedo=(1.0, 1.0, 1.0), phase="hg", g=G, aa_samples=4,
                  rbf_centres=cs.GAUSSIAN_CENTRES, rbf_scales=cs.GAUSSIAN_SCALES,
                  rbf_amplitudes=cs.GAUSSIAN_AMPLITUDES, **lights)
    exact = module.bake(**common, model="quadrature")["airlight"].astype(np.float64)
    fogshop = module.bake(**common, model="biri06")["airlight"].astype(np.float64)
    thin = dict(common, rbf_amplitudes=0.1 * cs.GAUSSIAN_AMPLITUDES)
    thin_exact = module.bake(**thin, model="quadrature")["airlight"].astype(np.float64)
    thin_fogshop = module.bake(**thin, model="biri06")["airlight"].astype(np.float64)
    c1, c2 = renders
    signal = exact[..., 0] > 0.02 * np.percentile(exact[..., 0], 99)
    noise = cs.seed_noise(c1, c2)
    SUMMARY.report(f"{kind}/cycles", seconds=seconds, samples=SAMPLES, pixels=int(signal.sum()),
                   noise_mean=float(noise[signal].mean()), noise_p99=float(np.percentile(noise[signal], 99)))
    return dict(cycles=0.5 * (c1 + c2), exact=exact, fogshop=fogshop, signal=signal, noise=noise,
                thin_exact=thin_exact, thin_fogshop=thin_fogshop, kind=kind)


def test01_exact_bake_matches_cycles_sun_hg(refs):
    """Sun + HG through the exact Gaussian path equals Cycles to noise, pixel by pixel and in
    total (same bounds as test_cycles_gaussians.py's point light)."""
    mask = refs["signal"]
    assert mask.sum() > 200
    mean, p99 = cs.channel_rel_stats(refs["exact"], refs["cycles"], mask)
    bias = cs.flux_bias(refs["cycles"], refs["exact"], mask)
    noise_mean = float(refs["noise"][mask].mean())
    noise_p99 = float(np.percentile(refs["noise"][mask], 99))
    SUMMARY.report(f"{refs['kind']}/exact_bake_vs_cycles", mean=mean, p99=p99, flux_bias=bias, noise_mean=noise_mean)
    assert abs(bias) < 0.01, bias
    assert mean < 1.5 * noise_mean + 0.005, (mean, noise_mean)
    if refs["kind"] == "spot":  # the pixels on the cone's edge (airlight varying at the pixel
        assert p99 < 0.6, p99    # scale: film filter vs the bake's edge samples); measured 0.47
    else:
        assert p99 < 1.5 * noise_p99 + 0.02, (p99, noise_p99)


def test02_fogshop_error_is_measured(refs):
    """Fogshop with the sun and HG on the same (thick) medium, against the exact bake and
    Cycles: reported; loose bounds so that a change in the approximation shows."""
    mask = refs["signal"]
    mean_q, p99_q = cs.channel_rel_stats(refs["fogshop"], refs["exact"], mask)
    mean_c, p99_c = cs.channel_rel_stats(refs["fogshop"], refs["cycles"], mask)
    SUMMARY.report(f"{refs['kind']}/fogshop_vs_exact", mean=mean_q, p99=p99_q)
    SUMMARY.report(f"{refs['kind']}/fogshop_vs_cycles", mean=mean_c, p99=p99_c)
    assert abs(mean_c - mean_q) < 0.05, (mean_c, mean_q)
    mean_t, p99_t = cs.channel_rel_stats(refs["thin_fogshop"], refs["thin_exact"], mask)
    SUMMARY.report(f"{refs['kind']}/fogshop_vs_exact_thin", mean=mean_t, p99=p99_t)
    if refs["kind"] != "sun":
        # The lamp sits next to the Gaussians (1/d^2, the phase and the spot profile sampled
        # at b_i^r: the paper's failure case, test_cycles_gaussians.py): measured point 39 %,
        # spot 41 %; at a tenth of the density still 22 % / 34 % (p99 100 % for the spot:
        # Gaussians whose b_i^r falls outside the cone get none of their lit part), i.e.
        # geometry, not attenuation.
        assert 0.05 < mean_q < 0.6, mean_q
        return
    assert 0.05 < mean_q < 0.4, mean_q          # measured 26 % (thick: not hidden, not zero)
    # The same Gaussians at a tenth of the density: the error falls with the optical depth
    # (measured 3.1 % mean, 5.8 % p99; the phase is constant along a sun's ray, so this is
    # the approximation of the attenuation alone).
    assert mean_t < 0.05 and p99_t < 0.1 and mean_t < 0.25 * mean_q, (mean_t, p99_t)
