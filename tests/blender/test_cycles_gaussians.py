"""Gaussian (Fogshop) fog: the Airlight bake vs Cycles, whose density is driven by the same
sum of Gaussians through shader nodes (issue 4's Cycles check).

    tools/blender.sh -b --python tests/blender/run_tests.py -- tests/blender/test_cycles_gaussians.py -s

Scene: tests/blender/cycles_scenes.py's Cycles recipe (single scattering: volume_bounces = 0,
black world, point light of radius 0, Blackman-Harris 1.5 px, float EXR) with no floor and
no homogeneous fog; instead a 7 m box holds a Volume Scatter (albedo 1, isotropic) whose
Density is sum_i c_i exp(-a_i^2 |P - b_i|^2) built from Geometry > Position with vector and
math nodes: the same medium the bake gets as rbf_centres/scales/amplitudes.

Cycles ray-marches heterogeneous volumes and is biased at its default step (NOTES.md: 59 %
mean error at step rate 1 on a 400 m domain). The step here is relative to the 7 m box:
measured with 256 samples, step rate 0.1 gave a total-flux bias of 0.15 % and step rate
0.02 the same 0.13 % (and 4x the time), so 0.1 is converged; the test uses it.

References: the bake's 'quadrature' model (adaptive quadrature of eq. 2 with exact Gaussian
optical depths: the exact single-scattering integral) is compared with Cycles to noise
(two seeds); the Fogshop approximation (the 'sun05' model's Gaussian path) is measured
against both and reported, not bounded tightly: these Gaussians are optically thick
(c sqrt(pi) / a up to 0.5) with the light close by, where the paper's per-Gaussian sampling
is known to fail (measured 29 % mean). Figures: out/test_artifacts/cycles_gaussians/summary.json.
"""

import os
import sys

import numpy as np
import pytest

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(HERE))
sys.path.insert(0, HERE)
import cycles_scenes as cs  # noqa: E402

ARTIFACTS = os.path.join(REPO, "out", "test_artifacts", "cycles_gaussians")
SEEDS = (1, 2)
SAMPLES = 128
STEP_RATE = cs.GAUSSIAN_STEP_RATE
CENTRES, SCALES, AMPLITUDES = cs.GAUSSIAN_CENTRES, cs.GAUSSIAN_SCALES, cs.GAUSSIAN_AMPLITUDES
SUMMARY = cs.Summary(ARTIFACTS, "[cycles_gaussians]", digits=4)


@pytest.fixture(scope="module")
def refs():
    from airlight import native
    _desc, scene = cs.gaussian_scene(SAMPLES, STEP_RATE)
    renders, seconds = cs.render_seeds(scene, ARTIFACTS, "cycles", SEEDS)
    seconds = sum(seconds)
    module = native.get()
    inputs = cs.bake_inputs(scene)
    common = dict(inputs, sigma_t=0.0, albedo=(1.0, 1.0, 1.0), phase="isotropic", g=0.0, aa_samples=4,
                  rbf_centres=CENTRES, rbf_scales=SCALES, rbf_amplitudes=AMPLITUDES)
    exact = module.bake(**common, model="quadrature")["airlight"].astype(np.float64)
    fogshop = module.bake(**common, model="sun05")["airlight"].astype(np.float64)
    refined = module.bake(**common, model="sun05", gaussian_accuracy=0.01)
    SUMMARY.report("refined_stats", **{k: refined["stats"][k] for k in (
        "gaussian_pairs", "gaussian_marched_lights", "gaussian_refine_abandoned", "seconds_refine")})
    c1, c2 = renders
    signal = exact[..., 0] > 0.02 * np.percentile(exact[..., 0], 99)
    noise = cs.seed_noise(c1, c2)
    SUMMARY.report("cycles", seconds=seconds, samples=SAMPLES, step_rate=STEP_RATE, pixels=int(signal.sum()),
                   noise_mean=float(noise[signal].mean()), noise_p99=float(np.percentile(noise[signal], 99)))
    return dict(cycles=0.5 * (c1 + c2), exact=exact, fogshop=fogshop, signal=signal, noise=noise,
                refined=refined["airlight"].astype(np.float64), refined_stats=refined["stats"])


def test01_exact_bake_matches_cycles(refs):
    """The bake's exact Gaussian path (quadrature of eq. 2, exact erf optical depths) equals
    Cycles' ray-marched medium to Monte Carlo noise, pixel by pixel and in total."""
    mask = refs["signal"]
    mean, p99 = cs.channel_rel_stats(refs["exact"], refs["cycles"], mask)
    bias = cs.flux_bias(refs["cycles"], refs["exact"], mask)
    noise_mean = float(refs["noise"][mask].mean())
    noise_p99 = float(np.percentile(refs["noise"][mask], 99))
    SUMMARY.report("exact_bake_vs_cycles", mean=mean, p99=p99, flux_bias=bias, noise_mean=noise_mean)
    assert abs(bias) < 0.01, bias                       # measured 0.15 % (256 spp)
    assert mean < 1.5 * noise_mean + 0.005, (mean, noise_mean)
    assert p99 < 1.5 * noise_p99 + 0.02, (p99, noise_p99)


def test02_fogshop_error_is_measured(refs):
    """Fogshop's approximation on the same medium, against the exact bake and Cycles. Its
    error is large here (thick Gaussians next to the light: the paper's failure case); the
    test pins the measured figure so a change in the approximation shows."""
    mask = refs["signal"]
    mean_q, p99_q = cs.channel_rel_stats(refs["fogshop"], refs["exact"], mask)
    mean_c, p99_c = cs.channel_rel_stats(refs["fogshop"], refs["cycles"], mask)
    SUMMARY.report("fogshop_vs_exact", mean=mean_q, p99=p99_q)
    SUMMARY.report("fogshop_vs_cycles", mean=mean_c, p99=p99_c)
    assert 0.05 < mean_q < 0.6, mean_q          # measured 29 % (not hidden, not zero)
    assert abs(mean_c - mean_q) < 0.05, (mean_c, mean_q)


def test03_refined_bake_meets_the_accuracy_and_matches_cycles(refs):
    """Automatic's refinement of Fogshop (gaussian_accuracy 1 %, what the add-on passes at the
    default Accuracy) on the same thick medium: within 1 % of the exact bake in mean and 3 % in
    p99, and Cycles' ray-marched medium to Monte Carlo noise."""
    mask = refs["signal"]
    assert not refs["refined_stats"]["gaussian_refine_abandoned"]
    mean_q, p99_q = cs.channel_rel_stats(refs["refined"], refs["exact"], mask)
    mean_c, p99_c = cs.channel_rel_stats(refs["refined"], refs["cycles"], mask)
    bias = cs.flux_bias(refs["cycles"], refs["refined"], mask)
    noise_mean = float(refs["noise"][mask].mean())
    noise_p99 = float(np.percentile(refs["noise"][mask], 99))
    SUMMARY.report("refined_vs_exact", mean=mean_q, p99=p99_q)
    SUMMARY.report("refined_vs_cycles", mean=mean_c, p99=p99_c, flux_bias=bias)
    assert mean_q <= 0.01 and p99_q <= 0.03, (mean_q, p99_q)
    assert abs(bias) < 0.01, bias
    assert mean_c < 1.5 * noise_mean + 0.005, (mean_c, noise_mean)
    assert p99_c < 1.5 * noise_p99 + 0.02, (p99_c, noise_p99)
