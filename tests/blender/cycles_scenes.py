"""Fog-only Cycles scenes used as external ground truth for the Airlight bake.

Shared by the tests/blender/test_cycles_*.py modules (and usable from benchmarks): the
scenes, the seeded renders and their noise, the pixel masks. Runs inside Blender (needs
bpy); the numpy helpers at the bottom need no Blender.

The scene follows the Cycles single-scattering recipe in shared NOTES.md:
volume_bounces = 0, a homogeneous Volume Scatter box (anisotropy 0, white) enclosing
camera and light, a point light of radius 0, a black world, view transform Standard,
denoising off, float EXR output, default film filter (Blackman-Harris 1.5 px).

Geometry of the default scene (metres, Blender Z up): the camera at (0, -8, 1.5)
looks along +Y, pitched 5 degrees down. A black floor (z = 0) ends at y = 2, i.e. ~10 m
in front of the camera, so its far edge is a silhouette against the infinite fog
(Dvp = inf above/behind it). The point light at (0.5, 6, 2.5) sits 4 m beyond that edge
and inside the view, so the fog behind the edge is bright and the floor's fog is dim:
a halo at the silhouette would show. Rays that pass beyond the edge stay at y > 2 and
are never shadowed by the floor (the analytic models ignore shadows), see _check_unshadowed.
"""

import math
import os
from dataclasses import dataclass

import numpy as np


@dataclass
class FogScene:
    """Plain description of the reference scene (no bpy objects)."""
    width: int = 128
    height: int = 96
    sigma_t: float = 0.15            # extinction, 1/m (albedo 1: sigma_s = sigma_t)
    light_power: float = 1000.0      # W; Cycles point light I0 = P / (4 pi) W/sr
    light_location: tuple = (0.5, 6.0, 2.5)
    camera_location: tuple = (0.0, -8.0, 1.5)
    camera_pitch_deg: float = -5.0   # below the horizon
    lens_mm: float = 50.0
    floor_x: tuple = (-20.0, 20.0)
    floor_y: tuple = (-15.0, 2.0)    # far edge at y = 2
    world_volume: bool = True        # medium as world volume (else a box)
    volume_half_size: float = 100.0  # half size of the Volume Scatter box, if a box
    samples: int = 256
    seed: int = 0
    threads: int = 2
    # Camera clip range. Cycles starts camera rays on the near plane (its fog begins at
    # view depth clip_start) and does not see surfaces beyond clip_end (measured here:
    # sky rays still get fog out to infinity). 1 m makes a bake that integrates from the
    # eye 16 % too dark (exp(0.15)), so the tests see it.
    clip_start: float = 1.0
    clip_end: float = 1000.0
    floor: bool = True               # the black floor (off for the halo scene)
    fog: bool = True                 # the world volume (off: the "render without fog")
    # Emissive rectangle facing the camera (halo scene): centre, half sizes (x, z),
    # strength. Emission seen through the fog is exactly render * T: it neither scatters
    # light into the fog (invisible to volume scatter, not sampled as a light) nor is
    # lit by the point light.
    emitter: tuple = None            # ((cx, cy, cz), (hx, hz), strength)
    # A wall at y = backdrop_y beyond clip_end (view depth > clip_end): Cycles never sees
    # it, and it casts no shadows, so the fog behind it is as if it were not there.
    backdrop_y: float = None

    @property
    def I0(self):
        return self.light_power / (4.0 * math.pi)


# ---------------------------------------------------------------------------------
# Blender side
# ---------------------------------------------------------------------------------

def _set_scatter(node, desc):
    node.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    node.inputs["Density"].default_value = desc.sigma_t
    node.inputs["Anisotropy"].default_value = 0.0


def build(desc: FogScene):
    """Replaces the current scene's content with _desc_; returns the bpy scene."""
    import bpy

    scene = bpy.context.scene
    for ob in list(scene.objects):
        bpy.data.objects.remove(ob, do_unlink=True)
    # Whatever the scene held before must not touch the renders: no compositing (the
    # add-on's fog nodes), no sequencer, no fog bake in render_pre.
    scene.use_nodes = False
    scene.render.use_compositing = False
    scene.render.use_sequencer = False
    if getattr(scene, "airlight", None) is not None:
        scene.airlight.enabled = False

    # Render settings: single scattering only, no denoising, float EXR.
    scene.render.engine = 'CYCLES'
    cy = scene.cycles
    cy.device = 'CPU'
    cy.samples = desc.samples
    cy.use_adaptive_sampling = False
    cy.use_denoising = False
    cy.seed = desc.seed
    cy.max_bounces = 0
    cy.volume_bounces = 0
    cy.diffuse_bounces = 0
    cy.glossy_bounces = 0
    cy.transmission_bounces = 0
    cy.transparent_max_bounces = 8
    cy.caustics_reflective = False
    cy.caustics_refractive = False
    cy.sample_clamp_direct = 0.0
    cy.sample_clamp_indirect = 0.0
    cy.pixel_filter_type = 'BLACKMAN_HARRIS'
    cy.filter_width = 1.5
    scene.render.resolution_x = desc.width
    scene.render.resolution_y = desc.height
    scene.render.resolution_percentage = 100
    scene.render.pixel_aspect_x = 1.0
    scene.render.pixel_aspect_y = 1.0
    scene.render.film_transparent = False
    scene.render.threads_mode = 'FIXED'
    scene.render.threads = desc.threads
    scene.render.use_persistent_data = False
    scene.view_settings.view_transform = 'Standard'
    scene.view_settings.look = 'None'
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0
    s = scene.render.image_settings
    s.file_format = 'OPEN_EXR'
    s.color_mode = 'RGB'
    s.color_depth = '32'
    s.exr_codec = 'ZIP'

    # Black world.
    # A new world each time: a reused one keeps the volume of an earlier build.
    world = bpy.data.worlds.new("RefWorld")
    scene.world = world
    world.use_nodes = True
    bg = world.node_tree.nodes.get("Background")
    if bg is not None:
        bg.inputs["Strength"].default_value = 0.0
        bg.inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
    world.color = (0.0, 0.0, 0.0)

    # Camera.
    cam_data = bpy.data.cameras.new("RefCamera")
    cam_data.lens = desc.lens_mm
    cam_data.sensor_fit = 'AUTO'
    cam_data.clip_start = desc.clip_start
    cam_data.clip_end = desc.clip_end
    cam = bpy.data.objects.new("RefCamera", cam_data)
    cam.location = desc.camera_location
    # Blender cameras look down -Z; rotate X by 90 deg to look along +Y, then pitch.
    cam.rotation_euler = (math.radians(90.0 + desc.camera_pitch_deg), 0.0, 0.0)
    scene.collection.objects.link(cam)
    scene.camera = cam

    # Black diffuse floor.
    if desc.floor:
        x0, x1 = desc.floor_x
        y0, y1 = desc.floor_y
        floor = _quad("RefFloor", [(x0, y0, 0), (x1, y0, 0), (x1, y1, 0), (x0, y1, 0)],
                      _black_material())
        scene.collection.objects.link(floor)
    if desc.emitter is not None:
        (cx, cy, cz), (hx, hz), strength = desc.emitter
        mat = bpy.data.materials.new("RefEmission")
        mat.use_nodes = True
        nodes, links = mat.node_tree.nodes, mat.node_tree.links
        for n in list(nodes):
            nodes.remove(n)
        out = nodes.new("ShaderNodeOutputMaterial")
        em = nodes.new("ShaderNodeEmission")
        em.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
        # Emission for camera rays only: Cycles 3.4 still lit the fog with the emitter
        # (measured: up to 2x the point light's airlight beside it) with sample_as_light
        # off and visible_volume_scatter off; Is Camera Ray is 0 for every other ray.
        path = nodes.new("ShaderNodeLightPath")
        mul = nodes.new("ShaderNodeMath")
        mul.operation = 'MULTIPLY'
        mul.inputs[1].default_value = strength
        links.new(path.outputs["Is Camera Ray"], mul.inputs[0])
        links.new(mul.outputs["Value"], em.inputs["Strength"])
        links.new(em.outputs["Emission"], out.inputs["Surface"])
        mat.cycles.sample_as_light = False
        emitter = _quad("RefEmitter", [(cx - hx, cy, cz - hz), (cx + hx, cy, cz - hz),
                                       (cx + hx, cy, cz + hz), (cx - hx, cy, cz + hz)], mat)
        emitter.visible_volume_scatter = False
        emitter.visible_shadow = False
        scene.collection.objects.link(emitter)
    if desc.backdrop_y is not None:
        y = desc.backdrop_y
        wall = _quad("RefBackdrop", [(-200, y, -200), (200, y, -200), (200, y, 200),
                                     (-200, y, 200)], _black_material())
        wall.visible_shadow = False
        wall.visible_volume_scatter = False
        scene.collection.objects.link(wall)

    # Homogeneous Volume Scatter medium: a world volume (default; no geometry, so any
    # exporter sees only the floor) or a box around the origin enclosing camera and light.
    if not desc.fog:
        pass
    elif desc.world_volume:
        nodes, links = world.node_tree.nodes, world.node_tree.links
        wout = next(n for n in nodes if n.bl_idname == "ShaderNodeOutputWorld")
        vs = nodes.new("ShaderNodeVolumeScatter")
        _set_scatter(vs, desc)
        links.new(vs.outputs["Volume"], wout.inputs["Volume"])
        world.cycles.homogeneous_volume = True
    else:
        h = desc.volume_half_size
        vmesh = bpy.data.meshes.new("RefFogBox")
        verts = [(sx * h, sy * h, sz * h) for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]
        faces = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4),
                 (1, 5, 7, 3)]
        vmesh.from_pydata(verts, [], faces)
        vmesh.validate()
        vmesh.update()
        box = bpy.data.objects.new("RefFogBox", vmesh)
        vmat = bpy.data.materials.new("RefFog")
        vmat.use_nodes = True
        nodes, links = vmat.node_tree.nodes, vmat.node_tree.links
        for n in list(nodes):
            nodes.remove(n)
        out = nodes.new("ShaderNodeOutputMaterial")
        vs = nodes.new("ShaderNodeVolumeScatter")
        _set_scatter(vs, desc)
        links.new(vs.outputs["Volume"], out.inputs["Volume"])
        vmesh.materials.append(vmat)
        vmat.cycles.homogeneous_volume = True
        scene.collection.objects.link(box)

    # Point light of radius 0.
    ldata = bpy.data.lights.new("RefLight", type='POINT')
    ldata.energy = desc.light_power
    ldata.color = (1.0, 1.0, 1.0)
    ldata.shadow_soft_size = 0.0
    light = bpy.data.objects.new("RefLight", ldata)
    light.location = desc.light_location
    scene.collection.objects.link(light)

    bpy.context.view_layer.update()
    return scene


def addon_ready():
    """Fails the calling test unless the add-on is registered (tools/blender.sh enables it;
    conftest's native_module has failed the session already without the compiled module)."""
    import bpy
    assert hasattr(bpy.types.Scene, "airlight") and hasattr(bpy.ops.airlight, "bake"), \
        "the add-on is not registered: run the tests through tools/blender.sh"


def render_seeds(scene, artifacts, stem, seeds):
    """Cycles renders of _scene_ with each of _seeds_ (float EXR <artifacts>/<stem>_seed<k>.exr):
    ([(H, W, 3) float64 per seed], [seconds per seed])."""
    os.makedirs(artifacts, exist_ok=True)
    renders, seconds = [], []
    for seed in seeds:
        path = os.path.join(artifacts, f"{stem}_seed{seed}.exr")
        seconds.append(render(scene, path, seed=seed))
        renders.append(read_exr_rgb(path).astype(np.float64))
    return renders, seconds


def seed_noise(c1, c2):
    """|c1 - c2| / (c1 + c2) of two renders with different seeds ((H, W, 3): the first
    channel; or (H, W)): the relative noise of their mean (|c1 - c2| / 2 has the spread of
    (c1 + c2) / 2), 0 where both are black."""
    c1, c2 = np.asarray(c1), np.asarray(c2)
    if c1.ndim == 3:
        c1, c2 = c1[..., 0], c2[..., 0]
    return np.abs(c1 - c2) / np.maximum(c1 + c2, 1e-30)


def noise_stats(noise, mask):
    """(mean, p99) of _noise_ over _mask_."""
    n = noise[mask]
    return float(n.mean()), float(np.percentile(n, 99))


def reference_rays(scene, desc: "FogScene", light_radius_px):
    """Per pixel of the fog-only scene _desc_ built in _scene_: dict(inputs (bake_inputs),
    o, d (rays from the near plane, as Cycles), depth (the floor's, from the eye), Dvp (from
    the ray start) and near_light (near_light's mask of _light_radius_px_))."""
    inputs = bake_inputs(scene)
    o, d = camera_rays(inputs["cam_to_world"], inputs["projection"], desc.width, desc.height)
    eye, _ = camera_rays(inputs["cam_to_world"], inputs["projection"], desc.width, desc.height, from_eye=True)
    depth = floor_depth(eye, d, desc)
    return dict(inputs=inputs, o=o, d=d, depth=depth, Dvp=floor_depth(o, d, desc),
                near_light=near_light(inputs, desc.width, desc.height, desc.light_location, light_radius_px))


def near_light(inputs, width, height, light_location, radius_px):
    """(H, W) mask of the pixels whose centres lie within _radius_px_ of the light's image
    (_inputs_: bake_inputs' camera)."""
    lx, ly = project_point(inputs["cam_to_world"], inputs["projection"], width, height, light_location)
    jj, ii = np.mgrid[0:height, 0:width]
    return np.hypot(ii + 0.5 - lx, jj + 0.5 - ly) < radius_px


class Summary:
    """Figures of one test module: printed as "<prefix> <name>: k=v, ..." (floats to
    _digits_ significant digits) and kept in <artifacts>/summary.json."""

    def __init__(self, artifacts, prefix, digits=5):
        self.artifacts, self.prefix, self.digits, self.figures = artifacts, prefix, digits, {}

    def report(self, name, **figures):
        import json
        self.figures[name] = figures
        os.makedirs(self.artifacts, exist_ok=True)
        with open(os.path.join(self.artifacts, "summary.json"), "w") as f:
            json.dump(self.figures, f, indent=2)
        print(f"{self.prefix} {name}: " + ", ".join(
            f"{k}={v:.{self.digits}g}" if isinstance(v, float) else f"{k}={v}" for k, v in figures.items()),
            flush=True)


def diffuse_floor(scene, albedo, diffuse_bounces):
    """Makes the reference floor a grey Lambert surface of _albedo_ and sets the bounce limits
    (max and diffuse) to _diffuse_bounces_."""
    floor = scene.objects["RefFloor"]
    bsdf = next(n for n in floor.active_material.node_tree.nodes if n.type == 'BSDF_DIFFUSE')
    bsdf.inputs["Color"].default_value = (albedo, albedo, albedo, 1.0)
    scene.cycles.max_bounces = diffuse_bounces
    scene.cycles.diffuse_bounces = diffuse_bounces


def block_means(img, n=8):
    """Means over n x n pixel blocks (rows and columns beyond a whole block dropped)."""
    H, W = img.shape
    return img[:H - H % n, :W - W % n].reshape(H // n, n, W // n, n).mean(axis=(1, 3))


def add_fog_slab(scene, top, sigma_t, anisotropy=0.0, half_size=1000.0):
    """A homogeneous Volume Scatter box "RefFogBox" (albedo 1) whose top face is at world
    height _top_ and whose sides and bottom lie _half_size_ away: a fog layer for sun lamps
    (an unbounded world volume would dim a sun to nothing). bake_inputs leaves it out."""
    import bpy
    L = half_size
    mesh = bpy.data.meshes.new("RefFogBox")
    verts = [(sx * L, sy * L, top if sz > 0 else -L) for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]
    faces = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    mesh.from_pydata(verts, [], faces)
    mesh.validate()
    mesh.update()
    mat = bpy.data.materials.new("RefFog")
    mat.use_nodes = True
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    for node in list(nodes):
        nodes.remove(node)
    out = nodes.new("ShaderNodeOutputMaterial")
    vs = nodes.new("ShaderNodeVolumeScatter")
    vs.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    vs.inputs["Density"].default_value = sigma_t
    vs.inputs["Anisotropy"].default_value = anisotropy
    links.new(vs.outputs["Volume"], out.inputs["Volume"])
    mesh.materials.append(mat)
    mat.cycles.homogeneous_volume = True
    box = bpy.data.objects.new("RefFogBox", mesh)
    scene.collection.objects.link(box)
    return box


def make_sun_lamp(light, direction, strength, color=(1.0, 1.0, 1.0)):
    """Turns the light object into a sun lamp of angle 0 shining along the unit vector
    _direction_ (its -Z), of strength (irradiance, W/m^2) _strength_."""
    from mathutils import Vector
    light.data.type = 'SUN'
    light.data.energy = strength
    light.data.color = color
    light.data.angle = 0.0
    light.rotation_mode = 'QUATERNION'
    light.rotation_quaternion = Vector((0.0, 0.0, -1.0)).rotation_difference(Vector(tuple(float(x) for x in direction)))


# The Gaussian-fog scenes (test_cycles_gaussians*.py): no floor and no homogeneous fog; a
# 7 m box holds a Volume Scatter (albedo 1) whose Density is sum_i c_i exp(-a_i^2 |P - b_i|^2),
# built from Geometry > Position with vector and math nodes: the medium the bake gets as
# rbf_centres / rbf_scales / rbf_amplitudes.
GAUSSIAN_CENTRES = np.array([[0.0, 2.0, 1.5], [0.8, 2.6, 1.2], [-0.7, 1.6, 1.9], [0.2, 3.2, 2.2]])
GAUSSIAN_SCALES = np.array([1.2, 1.0, 1.5, 0.9])
GAUSSIAN_AMPLITUDES = np.array([0.35, 0.25, 0.4, 0.2])
# Cycles' volume step rate there (relative to the box): converged, test_cycles_gaussians.py.
GAUSSIAN_STEP_RATE = 0.1


def gaussian_scene(samples, step_rate=GAUSSIAN_STEP_RATE):
    """(desc, scene) of the Gaussian-fog scene: 48 x 36 at _samples_, the camera 4 m before
    the Gaussians, a 300 W point light above them, Cycles' volume step rate _step_rate_."""
    desc = FogScene(width=48, height=36, fog=False, floor=False, samples=samples,
                    camera_location=(0.0, -4.0, 1.6), camera_pitch_deg=0.0, lens_mm=35.0,
                    light_location=(1.2, 1.0, 3.0), light_power=300.0, clip_start=0.1)
    scene = build(desc)
    _gaussian_box(scene, step_rate)
    return desc, scene


def _gaussian_box(scene, step_rate):
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
    for b, a, c in zip(GAUSSIAN_CENTRES, GAUSSIAN_SCALES, GAUSSIAN_AMPLITUDES):
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
    scene.cycles.volume_step_rate = step_rate
    scene.cycles.volume_max_steps = 4096
    bpy.context.view_layer.update()



def flux_bias(a, b, mask):
    """Relative difference of the total first channel of _a_ and _b_ over _mask_."""
    return float((a - b)[..., 0][mask].sum() / b[..., 0][mask].sum())


def channel_rel_stats(a, b, mask):
    """rel_stats of the first channels of (H, W, 3) images _a_ and _b_ (the reference)."""
    return rel_stats(a[..., 0], b[..., 0], mask)


def _black_material():
    import bpy
    mat = bpy.data.materials.new("RefBlack")
    mat.use_nodes = True
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    for n in list(nodes):
        nodes.remove(n)
    out = nodes.new("ShaderNodeOutputMaterial")
    diff = nodes.new("ShaderNodeBsdfDiffuse")
    diff.inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
    links.new(diff.outputs["BSDF"], out.inputs["Surface"])
    return mat


def _quad(name, corners, material):
    import bpy
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(corners, [], [(0, 1, 2, 3)])
    mesh.materials.append(material)
    return bpy.data.objects.new(name, mesh)


def addon_composite(scene, sigma_t, cache_dir, path, samples, seed, **settings):
    """The add-on as a user runs it on _scene_ (built without fog): scene.airlight on with
    density _sigma_t_, albedo 1, model SUN05, 2 threads, the cache in _cache_dir_ and the
    given _settings_ (surface_shading=..., volumetric_shadows=..., ...), bpy.ops.airlight.bake
    (light groups, passes, the compositor's frame), then a Cycles render at _samples_ with
    compositing to _path_; returns the (H, W) red channel, and leaves the fog off again."""
    import bpy
    st = scene.airlight
    st.density = sigma_t
    st.color = (1.0, 1.0, 1.0)
    st.model = 'SUN05'
    st.threads = 2
    st.cache_dir = cache_dir
    for key, value in settings.items():
        setattr(st, key, value)
    st.auto_composite = True
    st.enabled = True
    assert bpy.ops.airlight.bake('EXEC_DEFAULT') == {'FINISHED'}
    scene.render.use_compositing = True
    scene.cycles.samples = samples
    render(scene, path, seed=seed)
    image = read_exr_rgb(path)[..., 0].astype(np.float64)
    st.enabled = False
    return image


def render(scene, path, seed=None):
    """Renders the Combined pass to a float EXR at _path_; returns seconds taken."""
    import time
    import bpy

    if seed is not None:
        scene.cycles.seed = seed
    scene.render.filepath = path
    t0 = time.perf_counter()
    bpy.ops.render.render(write_still=True)
    return time.perf_counter() - t0


def bake_inputs(scene, exclude=("RefFogBox",)):
    """Keyword arguments for _native.bake exported from the Blender scene directly:
    the camera matrices as the contract defines them, world-space triangles of every
    mesh except the volume box, point lights with I0 = C * P / (4 pi)."""
    import bpy

    depsgraph = bpy.context.evaluated_depsgraph_get()
    r = scene.render
    W = int(r.resolution_x * r.resolution_percentage / 100)
    H = int(r.resolution_y * r.resolution_percentage / 100)
    cam = scene.camera
    proj = cam.calc_matrix_camera(depsgraph, x=W, y=H,
                                  scale_x=r.pixel_aspect_x, scale_y=r.pixel_aspect_y)
    verts, tris = [], []
    base = 0
    pos, inten = [], []
    for ob in scene.objects:
        if ob.type == 'MESH' and ob.name not in exclude:
            ev = ob.evaluated_get(depsgraph)
            me = ev.to_mesh()
            me.calc_loop_triangles()
            v = np.empty(len(me.vertices) * 3, np.float32)
            me.vertices.foreach_get("co", v)
            v = v.reshape(-1, 3)
            M = np.array(ob.matrix_world, dtype=np.float64)
            v = (v @ M[:3, :3].T + M[:3, 3]).astype(np.float32)
            t = np.empty(len(me.loop_triangles) * 3, np.uint32)
            me.loop_triangles.foreach_get("vertices", t)
            verts.append(v)
            tris.append(t.reshape(-1, 3) + base)
            base += len(v)
            ev.to_mesh_clear()
        elif ob.type == 'LIGHT' and ob.data.type == 'POINT':
            pos.append(tuple(ob.matrix_world.translation))
            c = np.array(ob.data.color, dtype=np.float64)
            inten.append(c * ob.data.energy / (4.0 * math.pi))
    return dict(
        width=W, height=H,
        cam_to_world=np.array(cam.matrix_world, dtype=np.float64),
        projection=np.array(proj, dtype=np.float64),
        clip_start=float(cam.data.clip_start), clip_end=float(cam.data.clip_end),
        vertices=np.concatenate(verts) if verts else np.zeros((0, 3), np.float32),
        triangles=np.concatenate(tris) if tris else np.zeros((0, 3), np.uint32),
        light_positions=np.array(pos, dtype=np.float64).reshape(-1, 3),
        light_intensities=np.array(inten, dtype=np.float64).reshape(-1, 3),
    )


# ---------------------------------------------------------------------------------
# numpy side (no bpy)
# ---------------------------------------------------------------------------------

def read_exr_rgb(path):
    """(H, W, 3) float32, top row first, of the first three channels of an EXR."""
    import OpenImageIO as oiio

    inp = oiio.ImageInput.open(path)
    if inp is None:
        raise RuntimeError(f"cannot open {path}: {oiio.geterror()}")
    try:
        spec = inp.spec()
        names = list(spec.channelnames)
        px = inp.read_image(0, spec.nchannels, oiio.FLOAT)
    finally:
        inp.close()
    px = np.asarray(px, dtype=np.float32).reshape(spec.height, spec.width, spec.nchannels)
    idx = [names.index(c) for c in ("R", "G", "B")] if all(
        c in names for c in ("R", "G", "B")) else [0, 1, 2]
    return px[:, :, idx]


def camera_rays(cam_to_world, projection, width, height, px=None, py=None, from_eye=False):
    """World-space origins and unit directions through film positions (pixels, from the
    top-left corner); pixel centres by default. Independent of the native camera code.
    Origins lie on the near clip plane, where Cycles starts camera rays (so its fog
    begins at clip_start: a factor exp(-sigma_t clip_start) on everything behind), or
    at the eye with _from_eye_ (perspective only), where depth is measured from."""
    if px is None:
        jj, ii = np.meshgrid(np.arange(height) + 0.5, np.arange(width) + 0.5, indexing="ij")
        px, py = ii, jj
    ndc_x = px / width * 2.0 - 1.0
    ndc_y = 1.0 - py / height * 2.0
    inv = np.linalg.inv(projection)
    def unproject(z):
        p = np.stack([ndc_x, ndc_y, np.full_like(ndc_x, z), np.ones_like(ndc_x)], -1) @ inv.T
        return p[..., :3] / p[..., 3:4]
    near, far = unproject(-1.0), unproject(1.0)
    d_cam = far - near
    if from_eye and projection[3, 3] == 0.0:
        near = np.zeros_like(near)
    o_w = near @ cam_to_world[:3, :3].T + cam_to_world[:3, 3]
    d_w = d_cam @ cam_to_world[:3, :3].T
    d_w /= np.linalg.norm(d_w, axis=-1, keepdims=True)
    return o_w, d_w


def floor_depth(o, d, desc: FogScene):
    """Distance to the floor rectangle z = 0 (inf where missed): analytic ray cast."""
    with np.errstate(divide="ignore", invalid="ignore"):
        t = -o[..., 2] / d[..., 2]
    hit = np.isfinite(t) & (t > 0)
    x = o[..., 0] + t * d[..., 0]
    y = o[..., 1] + t * d[..., 1]
    hit &= (x >= desc.floor_x[0]) & (x <= desc.floor_x[1])
    hit &= (y >= desc.floor_y[0]) & (y <= desc.floor_y[1])
    return np.where(hit, t, np.inf)


def quadrature_airlight(o, d, Dvp, light_pos, I0, sigma_t, n=256, phase=None):
    """Single-scattering airlight (Sun 2005 eq. 5, isotropic phase 1/(4 pi), albedo 1)
    by Gauss-Legendre quadrature, independent of the native code. With the foot of the
    perpendicular from the light at x0 = Dsv cos(gamma) and h = Dsv sin(gamma), the
    substitution x = x0 + h tan(theta) (dx / d^2 = d(theta) / h) turns the 1/d^2 peak
    into the smooth integrand sigma_t I0 / (4 pi h) * exp(-sigma_t (x + h sec(theta)))
    in theta.

    _phase_ (optional) is p(mu) with mu the cosine between the light's travel direction
    and the scattered one toward the eye (-d): the light -> x direction has component
    h tan(th) / (h sec(th)) = sin(th) along d, so mu = -sin(th). Default: 1/(4 pi)."""
    sv = np.asarray(light_pos, np.float64) - o
    Dsv = np.linalg.norm(sv, axis=-1)
    x0 = np.sum(sv * d, axis=-1)
    h = np.sqrt(np.maximum(Dsv ** 2 - x0 ** 2, 1e-300))
    th_a = np.arctan2(-x0, h)
    th_b = np.where(np.isfinite(Dvp), np.arctan2(np.where(np.isfinite(Dvp), Dvp, 0) - x0, h),
                    0.5 * np.pi)
    xg, wg = np.polynomial.legendre.leggauss(n)
    half = 0.5 * (th_b - th_a)[..., None]
    mid = 0.5 * (th_b + th_a)[..., None]
    th = mid + half * xg
    p = 1.0 / (4.0 * math.pi) if phase is None else phase(-np.sin(th))
    with np.errstate(over="ignore", invalid="ignore"):
        c = np.cos(th)
        expo = -sigma_t * (x0[..., None] + h[..., None] * (np.sin(th) + 1.0) / c)
        f = np.where(c > 0, p * np.exp(expo), 0.0)
    integral = np.sum(f * wg, axis=-1) * half[..., 0]
    return sigma_t * I0 * integral / h


def reference_image(desc: FogScene, cam_to_world, projection, n=256):
    """(H, W) airlight at pixel centres (from the near plane, as Cycles) and (H, W) depth
    (from the eye) for _desc_, by quadrature."""
    o, d = camera_rays(cam_to_world, projection, desc.width, desc.height)
    Dvp = floor_depth(o, d, desc)
    La = quadrature_airlight(o, d, Dvp, desc.light_location, desc.I0, desc.sigma_t, n=n)
    eye, _ = camera_rays(cam_to_world, projection, desc.width, desc.height, from_eye=True)
    return La, floor_depth(eye, d, desc)


def project_point(cam_to_world, projection, width, height, p):
    """Film position (px, py) in pixels of world point _p_."""
    w2c = np.linalg.inv(cam_to_world)
    pc = w2c @ np.array([*p, 1.0])
    clip = projection @ pc
    ndc = clip[:3] / clip[3]
    return (ndc[0] + 1.0) * 0.5 * width, (1.0 - ndc[1]) * 0.5 * height


def silhouette_mask(depth, radius=1):
    """Pixels whose (2r+1)^2 neighbourhood mixes finite and infinite depth."""
    fin = np.isfinite(depth)
    H, W = depth.shape
    pad = np.pad(fin, radius, mode="edge")
    anyf = np.zeros_like(fin)
    allf = np.ones_like(fin)
    for dy in range(-radius, radius + 1):
        for dx in range(-radius, radius + 1):
            s = pad[radius + dy:radius + dy + H, radius + dx:radius + dx + W]
            anyf |= s
            allf &= s
    return anyf & ~allf


def rel_stats(a, b, mask):
    """Mean and p99 of |a - b| / b over _mask_ (b the reference)."""
    r = np.abs(a[mask] - b[mask]) / b[mask]
    if r.size == 0:
        return float("nan"), float("nan")
    return float(np.mean(r)), float(np.percentile(r, 99))


def blackman_harris(x, width=1.5):
    """Cycles' 1D Blackman-Harris film filter for the UI's filter width _width_,
    unnormalised. Cycles' filter_table() doubles the width for this filter before
    evaluating filter_func_blackman_harris over [-width, width]: the support is
    |x| <= width (+-1.5 px by default), not width / 2 (checked against renders here:
    support +-0.75 px leaves 11 % mean error on silhouette pixels, +-1.5 px ~1 %)."""
    width = 2.0 * width
    v = 2.0 * math.pi * (x / width + 0.5)
    w = 0.35875 - 0.48829 * np.cos(v) + 0.14128 * np.cos(2 * v) - 0.01168 * np.cos(3 * v)
    return np.where(np.abs(x) <= 0.5 * width, w, 0.0)


def filtered_reference(desc: FogScene, cam_to_world, projection, pixels, k=16,
                       width=1.5, n=256):
    """Airlight of the listed (row, col) _pixels_ as the film filter sees it: Cycles'
    separable Blackman-Harris filter of _width_ px, integrated with a k x k midpoint grid
    over its support (+-_width_ px, see blackman_harris). Cycles importance-samples the
    same filter, so this is what its pixels converge to at silhouettes and around the
    light (unlike pixel centres). Residual: Cycles samples the filter through a lerped
    inverse-CDF table, which weights the far tails slightly differently; on the pixels
    1-2 px from a 3:1 contrast edge this leaves up to ~5 % (mean ~1 %)."""
    pixels = np.asarray(pixels).reshape(-1, 2)
    off = (np.arange(k) + 0.5) / k * 2.0 * width - width
    w1 = blackman_harris(off, width)
    w2 = (w1[:, None] * w1[None, :]).ravel()
    w2 /= w2.sum()
    ox, oy = np.meshgrid(off, off, indexing="xy")
    px = pixels[:, 1:2] + 0.5 + ox.ravel()[None, :]
    py = pixels[:, 0:1] + 0.5 + oy.ravel()[None, :]
    o, d = camera_rays(cam_to_world, projection, desc.width, desc.height, px, py)
    Dvp = floor_depth(o, d, desc)
    La = quadrature_airlight(o, d, Dvp, desc.light_location, desc.I0, desc.sigma_t, n=n)
    return La @ w2
