"""Spot lights in fog: the add-on's export + bake vs Cycles, and the export itself.

    tools/blender.sh -b --python tests/blender/run_tests.py -- tests/blender/test_cycles_spot.py -s

Scene: tests/blender/cycles_scenes.py's fog-only setup (world volume sigma_t = 0.15 /m,
albedo 1, black floor, volume_bounces = 0, clip_start 1 m, Blackman-Harris 1.5 px, 96x72
at 256 samples, two seeds: their mean is the reference and |c1 - c2| / (c1 + c2) its noise)
with the point light turned into a 1000 W spot of radius 0, size 90 deg, blend 1 (a smooth profile: the film filter blurs a sharp cone edge over +-1.5 px, which the pixel-centre bake does not), aimed
down and toward the camera, so the frame shows the lit cone and its soft edges.

Cycles' spot (NOTES.md): I = C P / (4 pi) cos(theta) smoothstep(0, (1 - cos(size/2)) blend,
cos(theta) - cos(size/2)). test01 checks the harness without native code: Cycles against a
numpy midpoint quadrature with that profile written out here (and that dropping the
cos(theta) factor would be visibly off). test02 bakes through scene_export (the add-on's
exporter: position, -Z axis, C P / (4 pi), spot_size, spot_blend) and _native.bake.
Pixels: "interior" = more than 2 px from any pixel with signal below 5 % of the p99 (the
cone's image edge), from the floor's silhouette (+-2 px) and from the lamp's image (4 px). Bounds: mean (p99) relative difference below the
reference's noise (mean, p99 of the noise estimate) plus 0.2 % (0.5 %) for Cycles' float
precision and film filter on smooth pixels, as in test_cycles_reference.py; the spot
quadrature itself is at 1e-5 relative. Measured here (2 x 256 samples, ~1.5 s of Cycles, 622
interior pixels): Cycles vs numpy quadrature mean 0.31 %, p99 1.76 % (noise 0.28 %, 1.49 %;
without the cos(theta) factor: mean 9.8 %); bake vs Cycles mean 0.31 %, p99 1.75 %; bake vs
quadrature p99 1.0e-6. Figures are written to out/test_artifacts/cycles_spot/summary.json.
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

ARTIFACTS = os.path.join(REPO, "out", "test_artifacts", "cycles_spot")
SEEDS = (1, 2)
SIGNAL_FLOOR = 0.05
LIGHT_RADIUS_PX = 4.0
SPOT_SIZE = math.radians(90.0)
SPOT_BLEND = 1.0
# Spot direction: down and back toward the camera (Blender Z up, camera looks along +Y).
SPOT_AXIS = np.array([-0.35, -0.5, -1.0]) / np.linalg.norm([-0.35, -0.5, -1.0])
SUMMARY = cs.Summary(ARTIFACTS, "[cycles_spot]", digits=4)


def spot_reference(o, d, Dvp, pos, axis, I0, sigma_t, size, blend, with_cos=True, n=6000, t_max=160.0):
    """sigma_t I0 / (4 pi) int_0^Dvp I(theta)/I0 e^{-sigma_t (|x - s| + t)} / |x - s|^2 dt by
    the midpoint rule on a grid dense near the eye (t = t_max u^2), independent of the native
    code; e^{-0.15 * 160} makes the cut-off negligible."""
    ch = math.cos(size / 2)
    e1 = (1 - ch) * blend
    u = (np.arange(n) + 0.5) / n
    t = t_max * u * u
    dt = 2 * t_max * u / n
    out = np.zeros(o.shape[:-1])
    flat_o, flat_d, flat_D = o.reshape(-1, 3), d.reshape(-1, 3), Dvp.reshape(-1)
    res = out.reshape(-1)
    for k in range(0, len(flat_o), 256):
        oo, dd, DD = flat_o[k:k + 256], flat_d[k:k + 256], flat_D[k:k + 256]
        x = oo[:, None, :] + t[None, :, None] * dd[:, None, :] - np.asarray(pos)[None, None, :]
        r2 = np.sum(x * x, axis=-1)
        r = np.sqrt(r2)
        c = (x @ axis) / r
        s = np.clip((c - ch) / e1, 0.0, 1.0) if e1 > 0 else (c > ch).astype(float)
        prof = np.where(c > ch, (c if with_cos else 1.0) * s * s * (3 - 2 * s) if e1 > 0 else
                        (c if with_cos else 1.0) * s, 0.0)
        f = prof * np.exp(-sigma_t * (r + t[None, :])) / r2 * dt[None, :]
        f[t[None, :] > DD[:, None]] = 0.0
        res[k:k + 256] = f.sum(axis=1)
    return sigma_t * I0 / (4 * math.pi) * out


def _make_spot(scene, desc):
    import bpy
    from mathutils import Vector
    light = bpy.data.objects["RefLight"]
    light.data.type = 'SPOT'
    light.data.spot_size = SPOT_SIZE
    light.data.spot_blend = SPOT_BLEND
    light.data.shadow_soft_size = 0.0
    light.data.energy = desc.light_power
    # Blender lights point down their -Z: rotate -Z onto the spot axis.
    light.rotation_mode = 'QUATERNION'
    light.rotation_quaternion = Vector((0.0, 0.0, -1.0)).rotation_difference(Vector(SPOT_AXIS.tolist()))
    bpy.context.view_layer.update()
    return light


@pytest.fixture(scope="module")
def refs():
    desc = cs.FogScene(width=96, height=72)
    scene = cs.build(desc)
    _make_spot(scene, desc)
    rays = cs.reference_rays(scene, desc, LIGHT_RADIUS_PX)
    o, d, depth, Dvp, near_light = (rays[k] for k in ("o", "d", "depth", "Dvp", "near_light"))
    (c1, c2), seconds = cs.render_seeds(scene, ARTIFACTS, "cycles_spot", SEEDS)
    seconds = sum(seconds)
    args = (o, d, Dvp, desc.light_location, SPOT_AXIS, desc.I0, desc.sigma_t, SPOT_SIZE, SPOT_BLEND)
    La = spot_reference(*args)
    La_nocos = spot_reference(*args, with_cos=False)
    # Away from the cone's image edge (+-2 px of where La < 5 % of its p99): there Cycles'
    # film filter blurs a fast profile over +-1.5 px while the bake holds pixel centres,
    # and the relative difference of a dim pixel says little (measured: median ratio
    # Cycles / quadrature 1.0000 everywhere; ratios to 1.6 at the edge pixels).
    dark = La < SIGNAL_FLOOR * np.percentile(La, 99)
    near_dark = dark.copy()
    for dj in range(-2, 3):
        for di in range(-2, 3):
            near_dark |= np.roll(np.roll(dark, dj, axis=0), di, axis=1)
    interior = ~near_dark & ~cs.silhouette_mask(depth, radius=2) & ~near_light
    noise = cs.seed_noise(c1, c2)
    SUMMARY.report("cycles", seconds=seconds, noise_mean=float(noise[interior].mean()),
                   noise_p99=float(np.percentile(noise[interior], 99)), interior_pixels=int(interior.sum()))
    return dict(desc=desc, scene=scene, cycles=0.5 * (c1 + c2), La=La, La_nocos=La_nocos, noise=noise,
                interior=interior)


def _noise(r):
    return cs.noise_stats(r["noise"], r["interior"])


def test01_cycles_matches_spot_quadrature(refs):
    """Harness check, no native code: Cycles' spot fog == numpy quadrature to noise."""
    C = refs["cycles"][..., 0]
    mean, p99 = cs.rel_stats(C, refs["La"], refs["interior"])
    nmean, np99 = _noise(refs)
    cmean, _ = cs.rel_stats(C, refs["La_nocos"], refs["interior"])
    SUMMARY.report("cycles_vs_spot_quadrature", mean=mean, p99=p99, noise_mean=nmean, noise_p99=np99,
                   without_cos_mean=cmean)
    assert refs["interior"].sum() > 300
    assert mean < 2.0 * nmean + 0.002, (mean, nmean)
    assert p99 < 2.0 * np99 + 0.005, (p99, np99)
    assert cmean > 2.0 * nmean + 0.01, cmean   # the cos(theta) factor is seen


def test02_spot_bake_matches_cycles(refs):
    """scene_export + _native.bake (model sun05 for the point part; spots by quadrature)."""
    import bpy
    from airlight import native, scene_export
    scene, desc = refs["scene"], refs["desc"]
    st = scene.airlight
    st.density = desc.sigma_t
    st.color = (1.0, 1.0, 1.0)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    description = scene_export.export_scene(scene, depsgraph)
    # The exporter: the spot and nothing else, with Blender's values.
    assert description["light_positions"].shape == (0, 3)
    np.testing.assert_allclose(description["spot_positions"][0], desc.light_location, atol=1e-6)
    np.testing.assert_allclose(description["spot_axes"][0], SPOT_AXIS, atol=1e-6)
    np.testing.assert_allclose(description["spot_intensities"][0], [desc.I0] * 3, rtol=1e-6)
    np.testing.assert_allclose(description["spot_size"], [SPOT_SIZE], rtol=1e-6)
    np.testing.assert_allclose(description["spot_blend"], [SPOT_BLEND], rtol=1e-6)
    result = native.get().bake(**description, threads=2)
    A = result["airlight"].astype(np.float64)
    C = refs["cycles"]
    nmean, np99 = _noise(refs)
    figures = {}
    for ch in range(3):
        mean, p99 = cs.rel_stats(A[..., ch], C[..., ch], refs["interior"])
        figures[f"mean_{'RGB'[ch]}"], figures[f"p99_{'RGB'[ch]}"] = mean, p99
    qmean, qp99 = cs.rel_stats(A[..., 0], refs["La"], refs["interior"])
    SUMMARY.report("bake_vs_cycles", noise_mean=nmean, noise_p99=np99, vs_quadrature_mean=qmean, vs_quadrature_p99=qp99,
                   seconds_airlight=float(result["stats"]["seconds_airlight"]), **figures)
    assert qp99 < 2e-3, qp99   # vs the midpoint reference (its own discretisation error, float32 output)
    for ch in range(3):
        assert figures[f"mean_{'RGB'[ch]}"] < nmean + 0.002, (ch, figures, nmean)
        assert figures[f"p99_{'RGB'[ch]}"] < np99 + 0.005, (ch, figures, np99)


def test03_non_participating_spot_is_not_exported(refs):
    import bpy
    from airlight import scene_export
    light = bpy.data.objects["RefLight"]
    light.data.airlight.participate = False
    light.data.update_tag()
    bpy.context.view_layer.update()
    try:
        description = scene_export.export_scene(refs["scene"], bpy.context.evaluated_depsgraph_get())
    finally:
        light.data.airlight.participate = True
        light.data.update_tag()
        bpy.context.view_layer.update()
    assert "spot_positions" not in description
