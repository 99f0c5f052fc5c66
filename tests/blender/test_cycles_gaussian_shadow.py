"""Gaussian fog crossing a shadow: volumetric shadows in fog objects, the bake vs Cycles.

    tools/blender.sh -b --python tests/blender/run_tests.py -- tests/blender/test_cycles_gaussian_shadow.py -s

Scene: test_cycles_gaussians.py's four Gaussians (cycles_scenes.gaussian_scene at 96 x 72, 128 samples: Cycles'
density is their sum through shader nodes, step rate 0.1 of the 7 m box, single scattering)
and its 300 W point light at (1.2, 1, 3), plus a black panel 0.3 m under the light (z = 2.7,
y >= PANEL_Y0) that covers the fog behind y ~ 1.3-1.6: the shadow's edge runs across the
Gaussians and across every view ray (the camera looks along +y), so each ray is lit in
front and dark behind, and Cycles' fog there is the front part only. Pixels: the exact bake's signal above 2 % of its p99,
away (2 px) from the panel's silhouette and (2 px) from the image's shadow edges (neighbours
whose lit share differs by more than 0.15), where the film filter blurs what the pixel-centre bake does not.

- test01: the bake's exact Gaussian path ('quadrature': adaptive quadrature with exact erf
  optical depths and a shadow ray per node) equals Cycles to noise, and Cycles' shadow is
  there (the unshadowed exact bake is far off).
- test02: the Fogshop models (model 'sun05', each Gaussian's terms restricted to the lit
  spans) against the exact bake and Cycles, measured and pinned.
Measured (3267 px, 77 % of them shadowed in part): exact bake vs Cycles 2.06 % mean / 8.2 %
p99 (noise 2.03 % / 7.9 %), flux 0.25 %, the unshadowed bake 104 % off; Fogshop shadowed
40.4 % / 77 % against the exact bake (unshadowed 28.4 %), the light it removes 67 % (exact
55 %). Figures: out/test_artifacts/cycles_gaussian_shadow/summary.json.
"""

import os
import sys

import numpy as np
import pytest

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(HERE))
sys.path.insert(0, HERE)
import cycles_scenes as cs  # noqa: E402

ARTIFACTS = os.path.join(REPO, "out", "test_artifacts", "cycles_gaussian_shadow")
SEEDS = (1, 2)
SAMPLES = 128
WIDTH, HEIGHT = 96, 72  # (gaussian_scene's 48 x 36 holds too few pixels away from the shadow's edge)
PANEL_Z, PANEL_Y0 = 2.7, 1.12
EDGE_JUMP = 0.15
SUMMARY = cs.Summary(ARTIFACTS, "[cycles_gaussian_shadow]", digits=4)


def _panel(scene):
    import bpy
    mesh = bpy.data.meshes.new("GaussPanel")
    mesh.from_pydata([(-6.0, PANEL_Y0, PANEL_Z), (6.0, PANEL_Y0, PANEL_Z), (6.0, 8.0, PANEL_Z),
                      (-6.0, 8.0, PANEL_Z)], [], [(0, 1, 2, 3)])
    mesh.materials.append(cs._black_material())
    scene.collection.objects.link(bpy.data.objects.new("GaussPanel", mesh))
    bpy.context.view_layer.update()


def _edges(lit):
    """Pixels within 2 px of a neighbour pair whose lit share (shadowed / unshadowed airlight)
    differs by more than EDGE_JUMP: the image's shadow edges (the Gaussians' own gradients
    are steep at this size too, so the share, not the airlight, finds them)."""
    jump = np.zeros(lit.shape, bool)
    for axis in (0, 1):
        jump |= np.abs(lit - np.roll(lit, 1, axis=axis)) > EDGE_JUMP
    near = np.zeros_like(jump)
    for dj in range(-2, 3):
        for di in range(-2, 3):
            near |= np.roll(np.roll(jump, dj, axis=0), di, axis=1)
    return near


@pytest.fixture(scope="module")
def refs():
    from airlight import native
    _desc, scene = cs.gaussian_scene(SAMPLES)
    scene.render.resolution_x, scene.render.resolution_y = WIDTH, HEIGHT
    _panel(scene)
    (c1, c2), seconds = cs.render_seeds(scene, ARTIFACTS, "cycles", SEEDS)
    module = native.get()
    inputs = cs.bake_inputs(scene)
    common = dict(inputs, sigma_t=0.0, albedo=(1.0, 1.0, 1.0), phase="isotropic", g=0.0, aa_samples=4,
                  rbf_centres=cs.GAUSSIAN_CENTRES, rbf_scales=cs.GAUSSIAN_SCALES,
                  rbf_amplitudes=cs.GAUSSIAN_AMPLITUDES, threads=2)

    def bake(model, shadows):
        return module.bake(**common, model=model, shadows=shadows)["airlight"].astype(np.float64)
    out = {f"{m}_{'on' if s else 'off'}": bake(m, s) for m in ("quadrature", "sun05") for s in (True, False)}
    exact = out["quadrature_on"][..., 0]
    depth = module.bake(**common, model="quadrature")["depth"].astype(np.float64)
    share = exact / np.maximum(out["quadrature_off"][..., 0], 1e-30)
    signal = (exact > 0.02 * np.percentile(exact, 99)) & ~cs.silhouette_mask(depth, radius=2) & ~_edges(share)
    noise = cs.seed_noise(c1, c2)
    nmean, np99 = cs.noise_stats(noise, signal)
    shadowed = float(np.mean(exact[signal] < 0.9 * out["quadrature_off"][..., 0][signal]))
    SUMMARY.report("cycles", seconds=sum(seconds), samples=SAMPLES, pixels=int(signal.sum()), noise_mean=nmean,
                   noise_p99=np99, shadowed_share=shadowed)
    return dict(out, cycles=0.5 * (c1 + c2), signal=signal, noise_mean=nmean, noise_p99=np99,
                shadowed=shadowed)


def test01_exact_shadowed_bake_matches_cycles(refs):
    mask = refs["signal"]
    mean, p99 = cs.channel_rel_stats(refs["quadrature_on"], refs["cycles"], mask)
    bias = cs.flux_bias(refs["cycles"], refs["quadrature_on"], mask)
    off_mean, _ = cs.channel_rel_stats(refs["quadrature_off"], refs["cycles"], mask)
    SUMMARY.report("exact_vs_cycles", mean=mean, p99=p99, flux_bias=bias, unshadowed_mean=off_mean)
    assert mask.sum() > 300, mask.sum()
    assert 0.2 < refs["shadowed"] < 0.8, refs["shadowed"]   # the shadow's edge crosses the fog
    assert abs(bias) < 0.01, bias
    assert mean < 1.5 * refs["noise_mean"] + 0.005, (mean, refs["noise_mean"])
    assert p99 < 1.5 * refs["noise_p99"] + 0.02, (p99, refs["noise_p99"])
    assert off_mean > 5.0 * (refs["noise_mean"] + 0.005), off_mean


def test02_fogshop_error_is_measured(refs):
    """Fogshop's approximation shadowed, against the exact bake and Cycles, with its error on
    the same Gaussians unshadowed beside it. These Gaussians are thick next to the light, the
    paper's failure case (unshadowed 28 % mean); the shadow adds to it here (40 %), because
    each Gaussian's light is taken at its point nearest the ray's line b_i^r, which for a
    Gaussian cut by the shadow's edge lies in the dark part while its lit part is nearer the
    light. The test pins the measured figures so that a change shows."""
    mask = refs["signal"]
    mean_on, p99_on = cs.channel_rel_stats(refs["sun05_on"], refs["quadrature_on"], mask)
    mean_off, p99_off = cs.channel_rel_stats(refs["sun05_off"], refs["quadrature_off"], mask)
    mean_c, p99_c = cs.channel_rel_stats(refs["sun05_on"], refs["cycles"], mask)
    removed_exact = 1.0 - refs["quadrature_on"][..., 0][mask].sum() / refs["quadrature_off"][..., 0][mask].sum()
    removed_fogshop = 1.0 - refs["sun05_on"][..., 0][mask].sum() / refs["sun05_off"][..., 0][mask].sum()
    SUMMARY.report("fogshop", shadowed_vs_exact_mean=mean_on, shadowed_vs_exact_p99=p99_on,
                   unshadowed_vs_exact_mean=mean_off, unshadowed_vs_exact_p99=p99_off, vs_cycles_mean=mean_c,
                   vs_cycles_p99=p99_c, removed_exact=removed_exact, removed_fogshop=removed_fogshop)
    assert 0.2 < mean_off < 0.4, mean_off          # measured 28.4 %
    assert 0.25 < mean_on < 0.55, mean_on          # measured 40.4 %
    assert abs(mean_c - mean_on) < 0.05, (mean_c, mean_on)
    assert abs(removed_fogshop - removed_exact) < 0.2, (removed_fogshop, removed_exact)  # 67 % vs 55 %
