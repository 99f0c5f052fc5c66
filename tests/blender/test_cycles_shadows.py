"""Volumetric shadows and light shafts: the add-on's export + bake vs Cycles.

    tools/blender.sh -b --python tests/blender/run_tests.py -- tests/blender/test_cycles_shadows.py -s

Four scenes on tests/blender/cycles_scenes.py's single-scattering setup (sigma_t = 0.15 /m,
albedo 1, black world, volume_bounces 0, clip_start 1 m, Blackman-Harris 1.5 px, 96 x 72 at
256 samples (1024 for the dimmer slats and roof), two seeds: their mean is the reference and
|c1 - c2| / (c1 + c2) its noise),
each with black occluders that Cycles' shadow rays stop at:
  - "panel": a 1000 W point light 1.5 m behind a black 2 x 2 m panel (one open quad) that
    hides it from the camera: the panel's silhouette is dark and its shadow cone runs
    towards the camera, whose rays cross it;
  - "window": a 1000 W point light 3 m behind a wall (y = 3) with a 2 x 2 m window, the
    camera in front of it inside the shaft: the fog before the wall is lit only inside the
    shaft, the rays through the window see the fog behind the wall and the light;
  - "slats": a 1000 W spot (90 deg, blend 1) shining down through eight slats 1.5 m under
    it: each view ray crosses up to sixteen lit and shadowed bands;
  - "roof": a sun (37 deg from the vertical) over a fog layer (top 6 m), under a roof
    (z = 4) with a 2 x 3 m opening, the camera under the roof: the fog is lit only in the
    opening's shaft and beyond the roof's edge.
test01 checks the harness without native code: Cycles against a numpy midpoint quadrature
with the occluders' visibility written out analytically (a segment to the light crossing the
wall outside the window, a slat, the roof outside its opening), and that the unshadowed
integral is visibly off. test02 bakes through scene_export (Volumetric Shadows on, the
lights' Cast Shadow; for the roof the fog box's faces are dropped, as test_cycles_sun.py
does) and _native.bake, and checks that shadows were asked for and that off differs.
Pixels: those whose reference is above 5 % of its p99, away (2 px) from silhouettes, from
the light's image (4 px) and from the image's shadow edges (neighbours more than 15 % apart
in the reference), where the film filter blurs a fast change the pixel-centre bake does not.
Bounds: mean (p99) relative difference below the reference's noise (mean, p99) plus 0.2 %
(0.5 %), as test_cycles_spot.py. test03: soft shadows, the panel's lamp with a 1 m Radius and
the roof's sun with a 5 deg Angle (1024 samples, the shadows' edges kept), baked with the
count Soft Shadow Samples Automatic takes at 1 %: mean within the noise plus 0.5 % (panel 16
samples 1.28 %, noise 1.06 %; roof 32 samples 2.20 %, noise 1.98 %), where one sample is
5.1 % and 6.0 % off. Figures: out/test_artifacts/cycles_shadows/summary.json.
Measured here (2 seeds; mean / p99 relative differences; noise the same statistics):
  panel (5306 px, all of them partly shadowed, the camera inside the shadow cone): Cycles vs
    quadrature 0.28 % / 0.94 % (noise 0.24 % / 0.81 %; unshadowed 36 %); bake vs Cycles
    0.28 % / 0.95 %, vs quadrature 3.0e-6 / 1.1e-5; off 59 %.
  window (5371 px, 98 % of them partly shadowed): Cycles vs quadrature 0.42 % / 1.38 % (noise
    0.39 % / 1.40 %; unshadowed 55 %); bake vs Cycles 0.42 % / 1.37 %, vs quadrature
    2.6e-6 / 8.0e-6; the bake with shadows off 141 % off.
  slats (2652 px, 1024 samples): Cycles vs quadrature 0.44 % / 1.46 % (noise 0.44 % / 1.46 %;
    unshadowed 50 %); bake vs Cycles 0.44 % / 1.47 %, vs quadrature 5.8e-6 / 3.6e-5; off 100 %.
  roof (607 px, 1024 samples): Cycles vs quadrature 0.50 % / 1.76 % (noise 0.54 % / 1.84 %;
    unshadowed 89 %); bake vs Cycles 0.50 % / 1.76 %, vs quadrature 1.3e-6 / 4.0e-6; off 820 %.
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

ARTIFACTS = os.path.join(REPO, "out", "test_artifacts", "cycles_shadows")
SEEDS = (1, 2)
SIGNAL_FLOOR = 0.05
EDGE_JUMP = 0.15
LIGHT_RADIUS_PX = 4.0
SIGMA_T = 0.15
SUMMARY = cs.Summary(ARTIFACTS, "[cycles_shadows]", digits=4)

# The window: wall y = WALL_Y, opening x in WINDOW_X, z in WINDOW_Z (the light at y = 6).
WALL_Y, WINDOW_X, WINDOW_Z = 3.0, (-0.5, 1.5), (1.5, 3.5)
# The panel: y = PANEL_Y, x in PANEL_X, z in PANEL_Z (the light at (0.5, 6, 2.5) behind it).
PANEL_Y, PANEL_X, PANEL_Z = 4.5, (-0.5, 1.5), (1.5, 3.5)
# The slats: z = SLAT_Z, each |x| < 6, y in [y0, y0 + SLAT_WIDTH] for y0 in SLAT_Y.
SLAT_Z, SLAT_WIDTH = 3.5, 0.3
SLAT_Y = tuple(3.15 + 0.6 * k for k in range(8))
SPOT_AT, SPOT_SIZE, SPOT_BLEND = (0.5, 6.0, 5.0), math.radians(90.0), 1.0
# The roof: z = ROOF_Z over |x|, |y| < ROOF_HALF, opening x in ROOF_X, y in ROOF_Y; the layer's top.
ROOF_Z, ROOF_HALF, ROOF_X, ROOF_Y, FOG_TOP = 4.0, 60.0, (-1.0, 1.0), (3.0, 6.0), 6.0
SUN_DIR = np.array([0.2, -0.6, -0.8]) / np.linalg.norm([0.2, -0.6, -0.8])
SUN_STRENGTH = 3.0


def _grid_with_hole(name, axis_values, plane, hole):
    """A black plane mesh of 3 x 3 cells, welded, the middle one (_hole_) left out:
    _axis_values_ = (us, vs) four values each, _plane_(u, v) -> (x, y, z)."""
    import bpy
    us, vs = axis_values
    verts = [plane(u, v) for v in vs for u in us]
    faces = [(j * 4 + i, j * 4 + i + 1, (j + 1) * 4 + i + 1, (j + 1) * 4 + i)
             for j in range(3) for i in range(3) if (i, j) != hole]
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(verts, [], faces)
    mesh.materials.append(cs._black_material())
    return bpy.data.objects.new(name, mesh)


def _build_window():
    desc = cs.FogScene(width=96, height=72, floor=False)
    scene = cs.build(desc)
    wall = _grid_with_hole("Wall", ((-40.0, *WINDOW_X, 40.0), (-40.0, *WINDOW_Z, 40.0)),
                           lambda u, v: (u, WALL_Y, v), (1, 1))
    scene.collection.objects.link(wall)
    return desc, scene


def _build_panel():
    import bpy
    desc = cs.FogScene(width=96, height=72, floor=False)
    scene = cs.build(desc)
    mesh = bpy.data.meshes.new("Panel")
    mesh.from_pydata([(PANEL_X[0], PANEL_Y, PANEL_Z[0]), (PANEL_X[1], PANEL_Y, PANEL_Z[0]),
                      (PANEL_X[1], PANEL_Y, PANEL_Z[1]), (PANEL_X[0], PANEL_Y, PANEL_Z[1])], [], [(0, 1, 2, 3)])
    mesh.materials.append(cs._black_material())
    scene.collection.objects.link(bpy.data.objects.new("Panel", mesh))
    return desc, scene


def _build_slats():
    import bpy
    from mathutils import Vector
    desc = cs.FogScene(width=96, height=72, floor=False, light_location=SPOT_AT, samples=1024)
    scene = cs.build(desc)
    light = bpy.data.objects["RefLight"]
    light.data.type = 'SPOT'
    light.data.spot_size = SPOT_SIZE
    light.data.spot_blend = SPOT_BLEND
    light.data.shadow_soft_size = 0.0
    light.rotation_mode = 'QUATERNION'
    light.rotation_quaternion = Vector((0.0, 0.0, -1.0)).rotation_difference(Vector((0.0, 0.0, -1.0)))
    mat = cs._black_material()
    for k, y0 in enumerate(SLAT_Y):
        mesh = bpy.data.meshes.new(f"Slat{k}")
        mesh.from_pydata([(-6.0, y0, SLAT_Z), (6.0, y0, SLAT_Z), (6.0, y0 + SLAT_WIDTH, SLAT_Z),
                          (-6.0, y0 + SLAT_WIDTH, SLAT_Z)], [], [(0, 1, 2, 3)])
        mesh.materials.append(mat)
        scene.collection.objects.link(bpy.data.objects.new(f"Slat{k}", mesh))
    return desc, scene


def _build_roof():
    import bpy
    # clip_end far beyond the box (test_cycles_sun.py: Cycles drops a volume segment ending at clip_end).
    desc = cs.FogScene(width=96, height=72, floor=False, fog=False, clip_end=1.0e5, samples=1024,
                       camera_location=(0.0, -8.0, 1.5), camera_pitch_deg=5.0)
    scene = cs.build(desc)
    cs.add_fog_slab(scene, FOG_TOP, SIGMA_T)
    cs.make_sun_lamp(bpy.data.objects["RefLight"], SUN_DIR, SUN_STRENGTH)
    roof = _grid_with_hole("Roof", ((-ROOF_HALF, *ROOF_X, ROOF_HALF), (-ROOF_HALF, *ROOF_Y, ROOF_HALF)),
                           lambda u, v: (u, v, ROOF_Z), (1, 1))
    scene.collection.objects.link(roof)
    return desc, scene


# -- analytic visibility and depth (numpy, no native code) ---------------------------------

def _crosses_outside(a, b, coord, level, box):
    """Per point pair (..., 3): whether segment a -> b crosses the plane x[coord] = level at a
    point outside _box_ ((axis, lo, hi) twice: the opening) -- i.e. on the solid part."""
    with np.errstate(divide="ignore", invalid="ignore"):
        u = (level - a[..., coord]) / (b[..., coord] - a[..., coord])
    crosses = (u > 0.0) & (u < 1.0)
    c = a + np.where(crosses, u, 0.0)[..., None] * (b - a)
    inside = np.ones(crosses.shape, dtype=bool)
    for axis, lo, hi in box:
        inside &= (c[..., axis] > lo) & (c[..., axis] < hi)
    return crosses, c, inside


def window_lit(p, light):
    crosses, _, inside = _crosses_outside(p, np.broadcast_to(light, p.shape), 1, WALL_Y,
                                          ((0, *WINDOW_X), (2, *WINDOW_Z)))
    return ~crosses | inside


def panel_lit(p, light):
    crosses, _, inside = _crosses_outside(p, np.broadcast_to(light, p.shape), 1, PANEL_Y,
                                          ((0, *PANEL_X), (2, *PANEL_Z)))
    return ~(crosses & inside)


def panel_depth(o, d):
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (PANEL_Y - o[..., 1]) / d[..., 1]
    x, z = o[..., 0] + t * d[..., 0], o[..., 2] + t * d[..., 2]
    on = (x > PANEL_X[0]) & (x < PANEL_X[1]) & (z > PANEL_Z[0]) & (z < PANEL_Z[1])
    return np.where((t > 0) & on, t, np.inf)


def slats_lit(p, light):
    crosses, c, _ = _crosses_outside(p, np.broadcast_to(light, p.shape), 2, SLAT_Z, ())
    on_slat = np.zeros(crosses.shape, dtype=bool)
    for y0 in SLAT_Y:
        on_slat |= (c[..., 1] > y0) & (c[..., 1] < y0 + SLAT_WIDTH) & (np.abs(c[..., 0]) < 6.0)
    return ~(crosses & on_slat)


def roof_lit(p):
    s = np.where(p[..., 2] < ROOF_Z, (ROOF_Z - p[..., 2]) / -SUN_DIR[2], 0.0)
    c = p - s[..., None] * SUN_DIR
    under = p[..., 2] < ROOF_Z
    on_roof = (np.abs(c[..., 0]) < ROOF_HALF) & (np.abs(c[..., 1]) < ROOF_HALF)
    opening = (c[..., 0] > ROOF_X[0]) & (c[..., 0] < ROOF_X[1]) & (c[..., 1] > ROOF_Y[0]) & (c[..., 1] < ROOF_Y[1])
    return ~(under & on_roof & ~opening)


def window_depth(o, d):
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (WALL_Y - o[..., 1]) / d[..., 1]
    x, z = o[..., 0] + t * d[..., 0], o[..., 2] + t * d[..., 2]
    hole = (x > WINDOW_X[0]) & (x < WINDOW_X[1]) & (z > WINDOW_Z[0]) & (z < WINDOW_Z[1])
    return np.where((t > 0) & ~hole, t, np.inf)


def roof_depth(o, d):
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (ROOF_Z - o[..., 2]) / d[..., 2]
    x, y = o[..., 0] + t * d[..., 0], o[..., 1] + t * d[..., 1]
    hole = (x > ROOF_X[0]) & (x < ROOF_X[1]) & (y > ROOF_Y[0]) & (y < ROOF_Y[1])
    on = (np.abs(x) < ROOF_HALF) & (np.abs(y) < ROOF_HALF)
    return np.where((t > 0) & on & ~hole, t, np.inf)


def spot_profile(x_minus_s):
    """Cycles' spot (NOTES.md) for the slats' spot, axis -Z: cos(theta) smoothstep."""
    r = np.linalg.norm(x_minus_s, axis=-1)
    c = -x_minus_s[..., 2] / r
    ch = math.cos(SPOT_SIZE / 2)
    s = np.clip((c - ch) / ((1 - ch) * SPOT_BLEND), 0.0, 1.0)
    return np.where(c > ch, c * s * s * (3 - 2 * s), 0.0)


def shadowed_midpoint(o, d, Dvp, integrand, lit, n=4000, t_max=160.0):
    """int_0^Dvp V(x) f(x, t) dt along each ray x = o + t d by the midpoint rule on cells
    t = t_max u^2 (u uniform), with _lit_ V's jumps found in each cell whose ends disagree (by
    bisection) and the cell's weight its lit length (so a jump costs O(dt^2), not O(dt));
    _lit_ None: V = 1. _integrand_(p, t) -> f, unshadowed, for points (..., 3)."""
    edges = t_max * (np.arange(n + 1) / n) ** 2
    lo, hi = edges[:-1], edges[1:]
    mid = t_max * ((np.arange(n) + 0.5) / n) ** 2
    out = np.zeros(o.shape[:-1])
    fo, fd, fD, res = o.reshape(-1, 3), d.reshape(-1, 3), Dvp.reshape(-1), out.reshape(-1)
    for k in range(0, len(fo), 64):
        ro, rd, rD = fo[k:k + 64, None, :], fd[k:k + 64, None, :], fD[k:k + 64, None]
        a, b = np.broadcast_to(lo, (len(ro), n)), np.minimum(hi[None, :], rD)
        length = np.maximum(b - a, 0.0)
        f = integrand(ro + mid[None, :, None] * rd, np.broadcast_to(mid, (len(ro), n)))
        if lit is not None:
            va, vb = lit(ro + a[..., None] * rd), lit(ro + b[..., None] * rd)
            weight = np.where(va, length, 0.0)
            jump = (va != vb) & (length > 0.0)
            if np.any(jump):
                ji, jc = np.nonzero(jump)
                x0, x1, v0 = a[ji, jc].copy(), b[ji, jc].copy(), va[ji, jc]
                for _ in range(40):
                    xm = 0.5 * (x0 + x1)
                    same = lit(fo[k + ji] + xm[:, None] * fd[k + ji]) == v0
                    x0, x1 = np.where(same, xm, x0), np.where(same, x1, xm)
                t_jump = 0.5 * (x0 + x1)
                weight[ji, jc] = np.where(v0, t_jump - a[ji, jc], b[ji, jc] - t_jump)
        else:
            weight = length
        res[k:k + 64] = np.sum(f * weight, axis=1)
    return out


def positional_reference(o, d, Dvp, light, I0, lit, profile=None):
    """sigma I0 / (4 pi) int_0^Dvp V prof e^{-sigma (t + |x - s|)} / |x - s|^2 dt (isotropic
    phase); with _lit_ None the unshadowed integral."""
    s = np.asarray(light, dtype=np.float64)

    def integrand(p, t):
        x = p - s
        r2 = np.sum(x * x, axis=-1)
        f = np.exp(-SIGMA_T * (np.sqrt(r2) + t)) / r2
        return f * profile(x) if profile is not None else f

    visible = (lambda p: lit(p, s)) if lit is not None else None
    return SIGMA_T * I0 / (4 * math.pi) * shadowed_midpoint(o, d, Dvp, integrand, visible)


def sun_reference(o, d, Dvp, shadowed=True):
    """sigma E p int V e^{-sigma t} e^{-sigma (top - z) / mu_s} dt over the ray's part inside
    the layer (z <= top; the camera is inside it) and before Dvp, isotropic phase, per unit E."""
    mu_s = -SUN_DIR[2]

    def integrand(p, t):
        return np.exp(-SIGMA_T * (t + np.maximum(FOG_TOP - p[..., 2], 0.0) / mu_s))

    def visible(p):
        return (p[..., 2] <= FOG_TOP) & (roof_lit(p) if shadowed else True)

    return SIGMA_T / (4 * math.pi) * shadowed_midpoint(o, d, Dvp, integrand, visible, t_max=250.0)


def _edges(La):
    """Pixels within 2 px of a jump of more than EDGE_JUMP between 4-neighbours."""
    jump = np.zeros(La.shape, dtype=bool)
    for axis in (0, 1):
        a, b = La, np.roll(La, 1, axis=axis)
        j = np.abs(a - b) > EDGE_JUMP * np.maximum(np.maximum(a, b), 1e-30)
        jump |= j | np.roll(j, -1, axis=axis)
    near = jump.copy()
    for dj in range(-2, 3):
        for di in range(-2, 3):
            near |= np.roll(np.roll(jump, dj, axis=0), di, axis=1)
    return near


SCENES = ("panel", "window", "slats", "roof")


@pytest.fixture(scope="module", params=SCENES)
def refs(request):
    name = request.param
    desc, scene = {"panel": _build_panel, "window": _build_window, "slats": _build_slats,
                   "roof": _build_roof}[name]()
    import bpy
    bpy.context.view_layer.update()
    inputs = cs.bake_inputs(scene)
    o, d = cs.camera_rays(inputs["cam_to_world"], inputs["projection"], desc.width, desc.height)
    eye, _ = cs.camera_rays(inputs["cam_to_world"], inputs["projection"], desc.width, desc.height, from_eye=True)
    if name == "panel":
        Dvp, depth = panel_depth(o, d), panel_depth(eye, d)
        La = positional_reference(o, d, Dvp, desc.light_location, desc.I0, panel_lit)
        La_open = positional_reference(o, d, Dvp, desc.light_location, desc.I0, None)
    elif name == "window":
        Dvp, depth = window_depth(o, d), window_depth(eye, d)
        La = positional_reference(o, d, Dvp, desc.light_location, desc.I0, window_lit)
        La_open = positional_reference(o, d, Dvp, desc.light_location, desc.I0, None)
    elif name == "slats":
        Dvp = depth = np.full(o.shape[:-1], np.inf)
        La = positional_reference(o, d, Dvp, SPOT_AT, desc.I0, slats_lit, spot_profile)
        La_open = positional_reference(o, d, Dvp, SPOT_AT, desc.I0, None, spot_profile)
    else:
        Dvp, depth = roof_depth(o, d), roof_depth(eye, d)
        La = SUN_STRENGTH * sun_reference(o, d, Dvp)
        La_open = SUN_STRENGTH * sun_reference(o, d, Dvp, shadowed=False)
    (c1, c2), seconds = cs.render_seeds(scene, ARTIFACTS, f"cycles_shadows_{name}", SEEDS)
    lamp = desc.light_location if name != "roof" else None
    near = cs.near_light(inputs, desc.width, desc.height, lamp, LIGHT_RADIUS_PX) if lamp else np.zeros_like(La, bool)
    # The signal floor from the pixels that see a surface when the light is seen through the
    # window (beside it the fog before the wall is dim).
    seen = La[np.isfinite(depth)] if name == "window" else La
    mask = ((La > SIGNAL_FLOOR * np.percentile(seen, 99)) & ~cs.silhouette_mask(depth, radius=2) & ~near
            & ~_edges(La))
    noise = cs.seed_noise(c1, c2)
    SUMMARY.report(f"{name}_cycles", seconds=sum(seconds), noise_mean=float(noise[mask].mean()),
                   noise_p99=float(np.percentile(noise[mask], 99)), pixels=int(mask.sum()),
                   shadowed_share=float(np.mean(La[mask] < 0.98 * La_open[mask])))
    return dict(name=name, desc=desc, scene=scene, cycles=0.5 * (c1 + c2), La=La, La_open=La_open, noise=noise,
                mask=mask)


def test01_cycles_matches_shadowed_quadrature(refs):
    """Harness check, no native code: Cycles' shadowed fog == the analytic-visibility quadrature."""
    C, mask = refs["cycles"][..., 0], refs["mask"]
    nmean, np99 = cs.noise_stats(refs["noise"], mask)
    mean, p99 = cs.rel_stats(C, refs["La"], mask)
    open_mean, _ = cs.rel_stats(C, refs["La_open"], mask)
    SUMMARY.report(f"{refs['name']}_cycles_vs_quadrature", mean=mean, p99=p99, noise_mean=nmean, noise_p99=np99,
                   unshadowed_mean=open_mean)
    assert mask.sum() > 500, mask.sum()
    assert mean < 2.0 * nmean + 0.002, (mean, nmean)
    assert p99 < 2.0 * np99 + 0.005, (p99, np99)
    assert open_mean > 5.0 * (nmean + 0.002), open_mean   # the shadows are what Cycles renders


def _bake_description(refs):
    import bpy
    from airlight import scene_export
    scene = refs["scene"]
    st = scene.airlight
    st.density = SIGMA_T
    st.color = (1.0, 1.0, 1.0)
    st.anisotropy = 0.0
    st.model = 'AUTO'
    st.volumetric_shadows = True
    if refs["name"] == "roof":
        st.use_fog_top = True
        st.fog_top = FOG_TOP
    description = scene_export.export_scene(scene, bpy.context.evaluated_depsgraph_get())
    key = {"panel": "light_shadows", "window": "light_shadows", "slats": "spot_shadows", "roof": "sun_shadows"}[refs["name"]]
    assert description.get("shadows") is True, sorted(description)
    np.testing.assert_array_equal(description[key], [1.0])
    if refs["name"] == "roof":  # the fog box bounds Cycles' medium: neither a surface nor a caster
        roof = bpy.data.objects["Roof"]
        v = np.array([roof.matrix_world @ vert.co for vert in roof.data.vertices], dtype=np.float32)
        t = np.array([tri.vertices[:] for tri in _triangles(roof.data)], dtype=np.uint32)
        description["vertices"], description["triangles"] = v, t
        description.pop("occluder_vertices", None)
        description.pop("occluder_triangles", None)
        description.pop("occluder_seen_triangles", None)
    return description


def _triangles(mesh):
    mesh.calc_loop_triangles()
    return mesh.loop_triangles


def test02_shadowed_bake_matches_cycles(refs):
    """scene_export + _native.bake with Volumetric Shadows, against Cycles and the quadrature."""
    from airlight import native
    description = _bake_description(refs)
    result = native.get().bake(**description, threads=2)
    A = result["airlight"].astype(np.float64)[..., 0]
    C, mask = refs["cycles"][..., 0], refs["mask"]
    nmean, np99 = cs.noise_stats(refs["noise"], mask)
    mean, p99 = cs.rel_stats(A, C, mask)
    qmean, qp99 = cs.rel_stats(A, refs["La"], mask)
    description["shadows"] = False
    off = native.get().bake(**description, threads=2)["airlight"].astype(np.float64)[..., 0]
    off_mean, _ = cs.rel_stats(off, C, mask)
    SUMMARY.report(f"{refs['name']}_bake_vs_cycles", mean=mean, p99=p99, noise_mean=nmean, noise_p99=np99,
                   vs_quadrature_mean=qmean, vs_quadrature_p99=qp99, shadows_off_mean=off_mean,
                   seconds_airlight=float(result["stats"]["seconds_airlight"]))
    assert qp99 < 1e-3, qp99   # vs the midpoint reference (its own discretisation, float32 output)
    assert mean < nmean + 0.002, (mean, nmean)
    assert p99 < np99 + 0.005, (p99, np99)
    assert off_mean > 5.0 * (nmean + 0.002), off_mean


# Soft shadows: the panel's lamp with a 1 m Radius, the roof's sun with a 5 deg Angle, at 1024
# samples; the bake with the count Soft Shadow Samples Automatic takes at 1 % (penumbra.py).
SOFT = {"panel": 1.0, "roof": math.radians(5.0)}
SOFT_MARGIN = 0.005  # Automatic at 1 % spends half of it on the samples


@pytest.fixture(scope="module", params=sorted(SOFT))
def soft(request):
    name = request.param
    desc, scene = {"panel": _build_panel, "roof": _build_roof}[name]()
    import bpy
    lamp = next(o for o in scene.objects if o.type == 'LIGHT')
    if lamp.data.type == 'SUN':
        lamp.data.angle = SOFT[name]
    else:
        lamp.data.shadow_soft_size = SOFT[name]
    scene.cycles.samples = 1024
    bpy.context.view_layer.update()
    inputs = cs.bake_inputs(scene)
    eye, d = cs.camera_rays(inputs["cam_to_world"], inputs["projection"], desc.width, desc.height, from_eye=True)
    depth = panel_depth(eye, d) if name == "panel" else roof_depth(eye, d)
    (c1, c2), _ = cs.render_seeds(scene, ARTIFACTS, f"cycles_soft_shadows_{name}", SEEDS)
    C = 0.5 * (c1 + c2)[..., 0]
    # Pixels as test02's but the shadows' edges kept: the penumbrae are what is tested.
    mask = (C > SIGNAL_FLOOR * np.percentile(C, 99)) & ~cs.silhouette_mask(depth, radius=2)
    if name == "panel":
        mask &= ~cs.near_light(inputs, desc.width, desc.height, desc.light_location, LIGHT_RADIUS_PX)
    return dict(name=name, scene=scene, cycles=C, noise=cs.seed_noise(c1, c2), mask=mask)


def test03_soft_shadows_match_cycles(soft):
    """A lamp's Radius and a sun's Angle soften the shafts' edges: the bake with Automatic's
    count of shadow samples is within Cycles' noise plus SOFT_MARGIN in mean, where the hard
    shadows (one sample) are well outside it."""
    from airlight import native, penumbra
    description = _bake_description(soft)
    assert penumbra.needed(description)
    samples = penumbra.choose(native.get(), description, dict(threads=2), 0.01).samples
    C, mask = soft["cycles"], soft["mask"]
    nmean, np99 = cs.noise_stats(soft["noise"], mask)
    mean, p99 = cs.rel_stats(native.get().bake(**description, threads=2, shadow_samples=samples)["airlight"]
                             .astype(np.float64)[..., 0], C, mask)
    hard, _ = cs.rel_stats(native.get().bake(**description, threads=2)["airlight"].astype(np.float64)[..., 0],
                           C, mask)
    SUMMARY.report(f"{soft['name']}_soft_shadows", samples=samples, mean=mean, p99=p99, noise_mean=nmean,
                   noise_p99=np99, hard_mean=hard, pixels=int(mask.sum()))
    assert samples > 1
    assert mean < nmean + SOFT_MARGIN, (samples, mean, nmean)
    assert hard > 2.0 * (nmean + SOFT_MARGIN), (hard, nmean)
