"""Sun lamps in a fog layer: the add-on's export + bake vs Cycles.

    tools/blender.sh -b --python tests/blender/run_tests.py -- tests/blender/test_cycles_sun.py -s

In Cycles an unbounded world-volume fog dims a sun to nothing (its light crosses infinite
fog), so the reference is a homogeneous Volume Scatter slab: a box whose top is at
FOG_TOP (world Z) and whose sides and bottom lie 1000 m away (e^{-0.15 * 1000}: nothing
reaches them or comes back), lit by a sun lamp of angle 0 and no geometry, black world,
tests/blender/cycles_scenes.py's single-scattering settings (volume_bounces 0, clip_start
1 m, Blackman-Harris 1.5 px), 96x72 at 256 samples, two seeds: their mean is the
reference and |c1 - c2| / (c1 + c2) its noise. Two views: the camera inside the layer
(1.5 m up, pitched 5 deg up: the upper rays leave through the top, the lower ones never
leave) and above it (6 m over the top, pitched 25 deg down: the rays enter through the
top; those above the horizon never do). The sun shines down at 37 deg from the vertical
towards the camera (so the upper rays look towards the sun), isotropic and an HG g = 0.5
phase (forward lobe).

test01 checks the harness without native code: Cycles against a numpy midpoint quadrature
of sigma E p int e^{-sigma (t - t_in)} e^{-sigma (top - z) / mu_s} over the part of the ray
inside the layer (sunlight_layer.h's integral written out here) - it is what tells that a sun's
strength is the irradiance E in W/m^2 and that its light is attenuated through the top.
test02 bakes through scene_export (direction = the lamp's -Z, E = colour * strength,
fog_top) and _native.bake. The box's own faces are dropped from the exported geometry:
the bake's fog is the scene's density, the box only bounds Cycles' medium.
Pixels: those whose reference is above 5 % of its p99 (rays that miss the layer are 0 in
both). Bounds: mean (p99) relative difference below the reference's noise (mean, p99)
plus 0.2 % (0.5 %), as test_cycles_spot.py. Figures: out/test_artifacts/cycles_sun/summary.json.
Measured here (2 x 256 samples, 6912 pixels per view, ~11-16 s of Cycles per view):
  inside, isotropic: Cycles vs quadrature mean 0.128 % p99 0.71 % (noise 0.114 %, 0.74 %);
    bake (sun05) vs Cycles mean 0.128 %, p99 0.70 %; the unbounded sun instead: mean 122 %.
  inside, HG g = 0.5: bake (biri06) vs Cycles mean 0.129 %, p99 0.69 % (noise 0.115 %, 0.74 %).
  above, isotropic: bake vs Cycles mean 0.010 %, p99 0.036 % (noise 0.009 %, 0.037 %);
    unbounded: 52 %.
  The constant-colour baseline (best least-squares colour) vs Cycles: mean 14.5 % (p99 37 %)
  inside isotropic, 44 % (145 %) inside g = 0.5, 10.1 % (20 %) above.
"""

import math
import os
import sys

import numpy as np
import pytest

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(HERE))
sys.path.insert(0, HERE)
import cycles_scenes as cs  # noqa: E402

ARTIFACTS = os.path.join(REPO, "out", "test_artifacts", "cycles_sun")
SEEDS = (1, 2)
SIGNAL_FLOOR = 0.05
SIGMA_T = 0.15
FOG_TOP = 6.0
SUN_STRENGTH = 3.0
SUN_COLOR = (1.0, 0.8, 0.6)
# Propagation direction: down and back toward the camera (which looks along +Y).
SUN_DIR = np.array([0.2, -0.6, -0.8]) / np.linalg.norm([0.2, -0.6, -0.8])
VIEWS = {
    "inside": dict(camera_location=(0.0, -8.0, 1.5), camera_pitch_deg=5.0),
    "above": dict(camera_location=(0.0, -8.0, FOG_TOP + 6.0), camera_pitch_deg=-25.0),
}
CASES = [("inside", 0.0), ("inside", 0.5), ("above", 0.0)]
SUMMARY = cs.Summary(ARTIFACTS, "[cycles_sun]", digits=4)


def hg(g, mu):
    return (1 - g * g) / (4 * math.pi * (1 + g * g - 2 * g * mu) ** 1.5)


def sun_reference(o, d, g, n=4000, t_max=250.0):
    """sigma E p(-w.d) int e^{-sigma (t - t_in)} e^{-sigma (top - z) / mu_s} dt over the
    ray's part inside the layer (z <= top), midpoint rule dense near the start
    (t = t_max u^2), per unit E (multiply by the colour * strength)."""
    mu_s = -SUN_DIR[2]
    u = (np.arange(n) + 0.5) / n
    t = t_max * u * u
    dt = 2 * t_max * u / n
    z = o[..., 2:3] + t * d[..., 2:3]                        # (H, W, n)
    inside = z <= FOG_TOP
    # Distance travelled inside the layer from the ray start: the layer is a half-space,
    # so the inside part is one interval; count the inside samples' steps.
    view = np.cumsum(inside * dt, axis=-1) - 0.5 * inside * dt
    f = np.where(inside, np.exp(-SIGMA_T * (view + (FOG_TOP - z) / mu_s)), 0.0) * dt
    p = hg(g, -(d @ SUN_DIR))
    return SIGMA_T * p * f.sum(axis=-1)


def _build(view, g):
    import bpy
    # clip_end far beyond the box: Cycles 3.4 drops the whole object-volume segment of a
    # camera ray that ends at clip_end inside the volume (measured: pixels exactly 0).
    desc = cs.FogScene(width=96, height=72, floor=False, fog=False, clip_end=1.0e5, **VIEWS[view])
    scene = cs.build(desc)
    # The slab: a Volume Scatter box with its top at FOG_TOP; the point light becomes a sun.
    cs.add_fog_slab(scene, FOG_TOP, SIGMA_T, g)
    cs.make_sun_lamp(bpy.data.objects["RefLight"], SUN_DIR, SUN_STRENGTH, SUN_COLOR)
    bpy.context.view_layer.update()
    return desc, scene


@pytest.fixture(scope="module", params=CASES, ids=[f"{v}-g{g}" for v, g in CASES])
def refs(request):
    view, g = request.param
    desc, scene = _build(view, g)
    inputs = cs.bake_inputs(scene)
    o, d = cs.camera_rays(inputs["cam_to_world"], inputs["projection"], desc.width, desc.height)
    (c1, c2), seconds = cs.render_seeds(scene, ARTIFACTS, f"cycles_sun_{view}_g{g}", SEEDS)
    seconds = sum(seconds)
    La = sun_reference(o, d, g)[..., None] * SUN_STRENGTH * np.asarray(SUN_COLOR)
    mask = La[..., 0] > SIGNAL_FLOOR * np.percentile(La[..., 0], 99)
    noise = cs.seed_noise(c1, c2)
    name = f"{view}_g{g}"
    SUMMARY.report(f"{name}_cycles", seconds=seconds, noise_mean=float(noise[mask].mean()),
                   noise_p99=float(np.percentile(noise[mask], 99)), pixels=int(mask.sum()))
    return dict(name=name, g=g, desc=desc, scene=scene, cycles=0.5 * (c1 + c2), La=La, noise=noise, mask=mask)


def _noise(r):
    return cs.noise_stats(r["noise"], r["mask"])


def test01_cycles_matches_sun_quadrature(refs):
    """Harness check, no native code: Cycles' sun in the slab == numpy quadrature to noise."""
    nmean, np99 = _noise(refs)
    figures = {}
    for ch in range(3):
        mean, p99 = cs.rel_stats(refs["cycles"][..., ch], refs["La"][..., ch], refs["mask"])
        figures[f"mean_{'RGB'[ch]}"], figures[f"p99_{'RGB'[ch]}"] = mean, p99
    # Without the sunlight's path through the top (Hoffman-Preetham's unattenuated sun):
    # must be visibly off, or this scene could not tell the two models apart.
    SUMMARY.report(f"{refs['name']}_cycles_vs_quadrature", noise_mean=nmean, noise_p99=np99, **figures)
    assert refs["mask"].sum() > 1000
    for ch in range(3):
        assert figures[f"mean_{'RGB'[ch]}"] < 2.0 * nmean + 0.002, (ch, figures, nmean)
        assert figures[f"p99_{'RGB'[ch]}"] < 2.0 * np99 + 0.005, (ch, figures, np99)


def test02_sun_bake_matches_cycles(refs):
    """scene_export + _native.bake (model sun05 / biri06 for the phase; suns in closed form)."""
    import bpy
    from airlight import model_choice, native, scene_export
    scene = refs["scene"]
    st = scene.airlight
    st.density = SIGMA_T
    st.color = (1.0, 1.0, 1.0)
    st.anisotropy = refs["g"]
    st.use_fog_top = True
    st.fog_top = FOG_TOP
    st.model = 'AUTO'
    depsgraph = bpy.context.evaluated_depsgraph_get()
    description = scene_export.export_scene(scene, depsgraph)
    np.testing.assert_allclose(description["sun_directions"][0], SUN_DIR, atol=1e-6)
    np.testing.assert_allclose(description["sun_irradiances"][0], SUN_STRENGTH * np.asarray(SUN_COLOR), rtol=1e-6)
    assert description["fog_top"] == pytest.approx(FOG_TOP)
    assert len(description["triangles"]) == 12     # the slab box only: not a surface for the fog
    description["vertices"] = np.zeros((0, 3), np.float32)
    description["triangles"] = np.zeros((0, 3), np.uint32)
    model = model_choice.choose(st)[0]
    result = native.get().bake(**description, model=model, threads=2)
    A = result["airlight"].astype(np.float64)
    C = refs["cycles"]
    nmean, np99 = _noise(refs)
    figures = {}
    for ch in range(3):
        mean, p99 = cs.rel_stats(A[..., ch], C[..., ch], refs["mask"])
        figures[f"mean_{'RGB'[ch]}"], figures[f"p99_{'RGB'[ch]}"] = mean, p99
    qmean, qp99 = cs.rel_stats(A[..., 0], refs["La"][..., 0], refs["mask"])
    SUMMARY.report(f"{refs['name']}_bake_vs_cycles", model=model, noise_mean=nmean, noise_p99=np99,
                   vs_quadrature_mean=qmean, vs_quadrature_p99=qp99,
                   seconds_airlight=float(result["stats"]["seconds_airlight"]), **figures)
    assert qp99 < 2e-3, qp99   # vs the midpoint reference (its discretisation error, float32 output)
    for ch in range(3):
        assert figures[f"mean_{'RGB'[ch]}"] < nmean + 0.002, (ch, figures, nmean)
        assert figures[f"p99_{'RGB'[ch]}"] < np99 + 0.005, (ch, figures, np99)
    # The unbounded (Hoffman-Preetham) sun would not match: the layer is what Cycles renders.
    description["fog_top"] = math.inf
    hp = native.get().bake(**description, model=model, threads=2)["airlight"].astype(np.float64)
    hp_mean, _ = cs.rel_stats(hp[..., 0], C[..., 0], refs["mask"])
    SUMMARY.report(f"{refs['name']}_unbounded_vs_cycles", mean=hp_mean)
    assert hp_mean > 5 * (nmean + 0.002), hp_mean
    # The bar: the constant-colour baseline (best least-squares colour) in the same view.
    description["fog_top"] = FOG_TOP
    base = native.get().bake(**description, model="baseline", threads=2)["airlight"].astype(np.float64)
    base_mean, base_p99 = cs.rel_stats(base[..., 0], C[..., 0], refs["mask"])
    SUMMARY.report(f"{refs['name']}_baseline_vs_cycles", mean=base_mean, p99=base_p99)
    assert base_mean > figures["mean_R"], (base_mean, figures["mean_R"])
