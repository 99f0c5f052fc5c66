"""Area lights in fog: the add-on's export + bake vs Cycles and vs a fine quadrature of the
true area integral.

    tools/blender.sh -b --python tests/blender/run_tests.py -- tests/blender/test_cycles_area.py -s

Scene: tests/blender/cycles_scenes.py's fog-only setup (world volume sigma_t = 0.15 /m,
albedo 1, black floor, volume_bounces 0, clip_start 1 m, 96 x 72, two seeds: their mean is
the reference and |c1 - c2| / (c1 + c2) its noise) with the point light turned into a 1000 W
area light (rectangle 3 x 1 m, and a disk of 2 m), aimed down and toward the camera.

Cycles' area light (addon/airlight/names.py AREA_INTENSITY): a one-sided Lambert emitter of
radiance C P / (4 A), so the fog at x receives sum over the area of C P / (4 A) cos(theta_l)
e^{-sigma r} / r^2 dA. The reference integrates that over a 24 x 8 grid of the rectangle (a
polar 16 x 24 grid of the disk) and along each ray by the midpoint rule; test01 holds Cycles
to it (the calibration of AREA_INTENSITY), test02 the bake (the light as scene_export's
spot samples) to Cycles and to it. Pixels: every other one each way (the reference's cost),
those with signal above 5 % of the p99, away from the floor's silhouette (2 px) and from the
light's image (10 px).
Measured here (256 samples, every other pixel; mean / p99 relative differences; Automatic at 1 %):
  rectangle 3 x 1 m (24 samples): Cycles vs quadrature 1.31 % / 7.9 % (noise 1.19 % / 6.5 %),
    total bias -0.004 %; bake vs quadrature 0.69 % / 15 % (near the light's image), vs Cycles
    1.63 % / 15 %;
  disk 2 m (25 samples): Cycles vs quadrature 1.41 % / 9.2 % (noise 1.48 % / 10.5 %), bias
    +0.41 %; bake vs quadrature 0.54 % / 3.5 %, vs Cycles 1.48 % / 9.2 %.
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

ARTIFACTS = os.path.join(REPO, "out", "test_artifacts", "cycles_area")
SEEDS = (1, 2)
SIGNAL_FLOOR = 0.05
LIGHT_RADIUS_PX = 10.0
AXIS = np.array([0.0, -0.5, -1.0]) / np.linalg.norm([0.0, -0.5, -1.0])
# name: (shape, size, size_y, Spread in degrees)
SHAPES = {"rectangle": ('RECTANGLE', 3.0, 1.0, 180.0), "disk": ('DISK', 2.0, 2.0, 180.0),
          "disk_spread": ('DISK', 2.0, 2.0, 50.0)}
SUMMARY = cs.Summary(ARTIFACTS, "[cycles_area]", digits=4)


def _make_area(scene, desc, shape, size, size_y, spread_deg):
    import bpy
    from mathutils import Vector
    light = bpy.data.objects["RefLight"]
    light.data.type = 'AREA'
    light.data.shape = shape
    light.data.size = size
    light.data.size_y = size_y
    light.data.spread = math.radians(spread_deg)
    light.data.energy = desc.light_power
    light.rotation_mode = 'QUATERNION'
    light.rotation_quaternion = Vector((0.0, 0.0, -1.0)).rotation_difference(Vector(AXIS.tolist()))
    bpy.context.view_layer.update()
    return light


def _area_points(light, shape, size, size_y):
    """World positions (n, 3) and their area weights (n,) of a fine grid over the light."""
    m = np.array(light.matrix_world, dtype=np.float64)
    if shape == 'RECTANGLE':
        nu, nv = 24, 8
        u = ((np.arange(nu) + 0.5) / nu - 0.5) * size
        v = ((np.arange(nv) + 0.5) / nv - 0.5) * size_y
        U, V = (a.ravel() for a in np.meshgrid(u, v))
        w = np.full(U.shape, 1.0 / U.size)
    else:
        nr, nphi = 16, 24
        r = np.sqrt((np.arange(nr) + 0.5) / nr) * 0.5 * size   # equal-area rings
        phi = (np.arange(nphi) + 0.5) / nphi * 2 * math.pi
        R, P = (a.ravel() for a in np.meshgrid(r, phi))
        U, V = R * np.cos(P), R * np.sin(P)
        w = np.full(U.shape, 1.0 / U.size)
    local = np.column_stack([U, V, np.zeros_like(U), np.ones_like(U)])
    return (local @ m.T)[:, :3], w


def area_reference(o, d, Dvp, points, weights, axis, power, sigma_t, spread=math.pi, n=800, t_max=120.0):
    """sigma/(4 pi) int_0^Dvp sum_k w_k (P/4) cos(theta_k) S(theta_k) e^{-sigma (r_k + t)} / r_k^2 dt
    by the midpoint rule on cells t = end u^2 (end = min(Dvp, t_max): e^{-0.15 * 120} beyond).
    S: Cycles 3.4's Spread (kernel/light/area.h), max(1 - tan(theta) / tan(h), 0) / (1 - h /
    tan(h)), h = spread / 2; 1 at 180 degrees."""
    h = 0.5 * spread
    H, W = o.shape[:2]
    out = np.full((H, W), np.nan)   # every other pixel each way (the rest NaN: not compared)
    u = np.arange(n + 1) / n
    for j in range(0, H, 2):
        for i in range(0, W, 2):
            edges = min(Dvp[j, i], t_max) * u * u
            t, dt = 0.5 * (edges[:-1] + edges[1:]), np.diff(edges)
            x = o[j, i] + t[:, None] * d[j, i]
            rel = x[:, None, :] - points[None, :, :]
            r2 = np.einsum("tkc,tkc->tk", rel, rel)
            r = np.sqrt(r2)
            cos = np.clip(np.einsum("tkc,c->tk", rel, axis) / r, 0.0, None)
            if spread < math.pi:
                with np.errstate(divide="ignore", invalid="ignore"):
                    tan = np.sqrt(np.maximum(0.0, 1.0 - cos * cos)) / cos
                cos = np.where(cos > 0.0, cos * np.clip(1.0 - tan / math.tan(h), 0.0, None), 0.0) / (1.0 - h / math.tan(h))
            f = (weights[None, :] * (power / 4.0) * cos * np.exp(-sigma_t * r) / r2).sum(axis=1)
            out[j, i] = sigma_t / (4 * math.pi) * np.sum(f * np.exp(-sigma_t * t) * dt)
    return out


@pytest.fixture(scope="module", params=sorted(SHAPES))
def refs(request):
    name = request.param
    shape, size, size_y, spread_deg = SHAPES[name]
    # (a narrow Spread lights few pixels from few directions: Cycles needs more samples there)
    desc = cs.FogScene(width=96, height=72, samples=256 if spread_deg >= 180.0 else 2048)
    scene = cs.build(desc)
    light = _make_area(scene, desc, shape, size, size_y, spread_deg)
    rays = cs.reference_rays(scene, desc, LIGHT_RADIUS_PX)
    o, d, depth, Dvp, near_light = (rays[k] for k in ("o", "d", "depth", "Dvp", "near_light"))
    (c1, c2), seconds = cs.render_seeds(scene, ARTIFACTS, f"cycles_area_{name}", SEEDS)
    points, weights = _area_points(light, shape, size, size_y)
    La = area_reference(o, d, Dvp, points, weights, AXIS, desc.light_power, desc.sigma_t, math.radians(spread_deg))
    finite = np.isfinite(La)
    mask = finite & (np.where(finite, La, 0.0) > SIGNAL_FLOOR * np.nanpercentile(La, 99))
    mask &= ~cs.silhouette_mask(depth, radius=2) & ~near_light
    noise = cs.seed_noise(c1, c2)
    SUMMARY.report(f"{name}_cycles", seconds=sum(seconds), noise_mean=float(noise[mask].mean()),
                   noise_p99=float(np.percentile(noise[mask], 99)), pixels=int(mask.sum()))
    return dict(name=name, desc=desc, scene=scene, cycles=0.5 * (c1 + c2), La=La, noise=noise, mask=mask)


def test01_cycles_matches_area_quadrature(refs):
    """Harness and calibration, no native code: Cycles' area light == the area integral."""
    C, mask = refs["cycles"][..., 0], refs["mask"]
    mean, p99 = cs.rel_stats(C, refs["La"], mask)
    nmean, np99 = cs.noise_stats(refs["noise"], mask)
    bias = float(C[mask].sum() / refs["La"][mask].sum() - 1.0)
    SUMMARY.report(f"{refs['name']}_cycles_vs_quadrature", mean=mean, p99=p99, noise_mean=nmean, noise_p99=np99,
                   bias=bias)
    assert mask.sum() > 300 / 4
    assert abs(bias) < 0.01, bias
    assert mean < 2.0 * nmean + 0.005, (mean, nmean)


def test02_area_bake_matches_cycles(refs):
    """scene_export (the light as spot samples) + _native.bake against Cycles and the area integral."""
    import bpy
    from airlight import native, scene_export
    scene, desc = refs["scene"], refs["desc"]
    st = scene.airlight
    st.density = desc.sigma_t
    st.color = (1.0, 1.0, 1.0)
    description = scene_export.export_scene(scene, bpy.context.evaluated_depsgraph_get())
    n = len(description["spot_positions"])
    assert n >= 4 and description["light_positions"].shape == (0, 3)
    np.testing.assert_allclose(description["spot_intensities"].sum(axis=0), [desc.light_power / 4.0] * 3, rtol=1e-9)
    result = native.get().bake(**description, threads=2)
    A = result["airlight"].astype(np.float64)[..., 0]
    C, mask = refs["cycles"][..., 0], refs["mask"]
    mean, p99 = cs.rel_stats(A, C, mask)
    qmean, qp99 = cs.rel_stats(A, refs["La"], mask)
    nmean, np99 = cs.noise_stats(refs["noise"], mask)
    SUMMARY.report(f"{refs['name']}_bake_vs_cycles", samples=n, mean=mean, p99=p99, noise_mean=nmean, noise_p99=np99,
                   vs_quadrature_mean=qmean, vs_quadrature_p99=qp99,
                   seconds_airlight=float(result["stats"]["seconds_airlight"]))
    # Automatic at the default 1 %: the sample count (names.area_cell) meets it beyond the
    # light's image.
    assert st.model == 'AUTO' and st.accuracy == 1.0
    assert qmean < 0.01, qmean
    assert mean < nmean + 0.01, (mean, nmean)
