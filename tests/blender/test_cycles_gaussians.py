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

import json
import os
import sys

import numpy as np
import pytest

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(HERE))
sys.path.insert(0, HERE)
import cycles_scenes as cs  # noqa: E402
from conftest import needs_real_native  # noqa: E402

ARTIFACTS = os.path.join(REPO, "out", "test_artifacts", "cycles_gaussians")
SEEDS = (1, 2)
SAMPLES = 128
STEP_RATE = 0.1
CENTRES = np.array([[0.0, 2.0, 1.5], [0.8, 2.6, 1.2], [-0.7, 1.6, 1.9], [0.2, 3.2, 2.2]])
SCALES = np.array([1.2, 1.0, 1.5, 0.9])
AMPLITUDES = np.array([0.35, 0.25, 0.4, 0.2])
SUMMARY = {}


def _report(name, **figures):
    SUMMARY[name] = figures
    print(f"[cycles_gaussians] {name}: " + ", ".join(
        f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}" for k, v in figures.items()))
    os.makedirs(ARTIFACTS, exist_ok=True)
    with open(os.path.join(ARTIFACTS, "summary.json"), "w") as f:
        json.dump(SUMMARY, f, indent=2)


def _gaussian_box(scene):
    """A box around the Gaussians whose Volume Scatter density is their sum (shader nodes)."""
    import bpy
    h = 3.5
    mesh = bpy.data.meshes.new("RefFogBox")
    verts = [(sx * h, sy * h, sz * h) for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]
    faces = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    mesh.from_pydata(verts, [], faces)
    box = bpy.data.objects.new("RefFogBox", mesh)
    box.location = (0.0, 2.3, 1.6)
    mat = bpy.data.materials.new("RefGaussians")
    mat.use_nodes = True
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    for n in list(nodes):
        nodes.remove(n)
    out = nodes.new("ShaderNodeOutputMaterial")
    scatter = nodes.new("ShaderNodeVolumeScatter")
    scatter.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    scatter.inputs["Anisotropy"].default_value = 0.0
    geometry = nodes.new("ShaderNodeNewGeometry")
    total = None
    for b, a, c in zip(CENTRES, SCALES, AMPLITUDES):
        sub = nodes.new("ShaderNodeVectorMath")
        sub.operation = 'SUBTRACT'
        links.new(geometry.outputs["Position"], sub.inputs[0])
        sub.inputs[1].default_value = tuple(b)
        dot = nodes.new("ShaderNodeVectorMath")
        dot.operation = 'DOT_PRODUCT'
        links.new(sub.outputs[0], dot.inputs[0])
        links.new(sub.outputs[0], dot.inputs[1])
        arg = nodes.new("ShaderNodeMath")
        arg.operation = 'MULTIPLY'
        links.new(dot.outputs["Value"], arg.inputs[0])
        arg.inputs[1].default_value = -a * a
        gauss = nodes.new("ShaderNodeMath")
        gauss.operation = 'EXPONENT'
        links.new(arg.outputs[0], gauss.inputs[0])
        term = nodes.new("ShaderNodeMath")
        term.operation = 'MULTIPLY'
        links.new(gauss.outputs[0], term.inputs[0])
        term.inputs[1].default_value = c
        if total is None:
            total = term
        else:
            add = nodes.new("ShaderNodeMath")
            add.operation = 'ADD'
            links.new(total.outputs[0], add.inputs[0])
            links.new(term.outputs[0], add.inputs[1])
            total = add
    links.new(total.outputs[0], scatter.inputs["Density"])
    links.new(scatter.outputs["Volume"], out.inputs["Volume"])
    mat.cycles.homogeneous_volume = False
    mesh.materials.append(mat)
    scene.collection.objects.link(box)
    scene.cycles.volume_step_rate = STEP_RATE
    scene.cycles.volume_max_steps = 4096
    bpy.context.view_layer.update()


@pytest.fixture(scope="module")
def refs():
    import bpy  # noqa: F401
    from airlight import native
    if not native.available() or native.get().__name__ == "fake_native":
        pytest.skip("needs the compiled _native module")
    os.makedirs(ARTIFACTS, exist_ok=True)
    desc = cs.FogScene(width=48, height=36, fog=False, floor=False, samples=SAMPLES,
                       camera_location=(0.0, -4.0, 1.6), camera_pitch_deg=0.0, lens_mm=35.0,
                       light_location=(1.2, 1.0, 3.0), light_power=300.0, clip_start=0.1)
    scene = cs.build(desc)
    _gaussian_box(scene)
    renders, seconds = [], 0.0
    for seed in SEEDS:
        path = os.path.join(ARTIFACTS, f"cycles_seed{seed}.exr")
        seconds += cs.render(scene, path, seed=seed)
        renders.append(cs.read_exr_rgb(path).astype(np.float64))
    module = native.get()
    inputs = cs.bake_inputs(scene)
    common = dict(inputs, sigma_t=0.0, albedo=(1.0, 1.0, 1.0), phase="isotropic", g=0.0, aa_samples=4,
                  rbf_centres=CENTRES, rbf_scales=SCALES, rbf_amplitudes=AMPLITUDES)
    exact = module.bake(**common, model="quadrature")["airlight"].astype(np.float64)
    fogshop = module.bake(**common, model="sun05")["airlight"].astype(np.float64)
    c1, c2 = renders
    signal = exact[..., 0] > 0.02 * np.percentile(exact[..., 0], 99)
    noise = (np.abs(c1 - c2) / (c1 + c2))[..., 0]
    _report("cycles", seconds=seconds, samples=SAMPLES, step_rate=STEP_RATE, pixels=int(signal.sum()),
            noise_mean=float(noise[signal].mean()), noise_p99=float(np.percentile(noise[signal], 99)))
    return dict(cycles=0.5 * (c1 + c2), exact=exact, fogshop=fogshop, signal=signal, noise=noise)


def _rel(a, b, mask):
    r = (np.abs(a - b) / b)[..., 0][mask]
    return float(r.mean()), float(np.percentile(r, 99))


def _flux_bias(a, b, mask):
    return float((a - b)[..., 0][mask].sum() / b[..., 0][mask].sum())


@needs_real_native
def test01_exact_bake_matches_cycles(refs):
    """The bake's exact Gaussian path (quadrature of eq. 2, exact erf optical depths) equals
    Cycles' ray-marched medium to Monte Carlo noise, pixel by pixel and in total."""
    mask = refs["signal"]
    mean, p99 = _rel(refs["exact"], refs["cycles"], mask)
    bias = _flux_bias(refs["cycles"], refs["exact"], mask)
    noise_mean = float(refs["noise"][mask].mean())
    noise_p99 = float(np.percentile(refs["noise"][mask], 99))
    _report("exact_bake_vs_cycles", mean=mean, p99=p99, flux_bias=bias, noise_mean=noise_mean)
    assert abs(bias) < 0.01, bias                       # measured 0.15 % (256 spp)
    assert mean < 1.5 * noise_mean + 0.005, (mean, noise_mean)
    assert p99 < 1.5 * noise_p99 + 0.02, (p99, noise_p99)


@needs_real_native
def test02_fogshop_error_is_measured(refs):
    """Fogshop's approximation on the same medium, against the exact bake and Cycles. Its
    error is large here (thick Gaussians next to the light: the paper's failure case); the
    test pins the measured figure so a change in the approximation shows."""
    mask = refs["signal"]
    mean_q, p99_q = _rel(refs["fogshop"], refs["exact"], mask)
    mean_c, p99_c = _rel(refs["fogshop"], refs["cycles"], mask)
    _report("fogshop_vs_exact", mean=mean_q, p99=p99_q)
    _report("fogshop_vs_cycles", mean=mean_c, p99=p99_c)
    assert 0.05 < mean_q < 0.6, mean_q          # measured 29 % (not hidden, not zero)
    assert abs(mean_c - mean_q) < 0.05, (mean_c, mean_q)
