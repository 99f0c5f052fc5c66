"""The World seen through fog (addon/airlight/environment.py, native sun05_psf).

- The equirectangular mapping the native side uses is Blender's: a Cycles render of a World
  whose Environment Texture encodes (u, v) in its colour equals `_native.environment_view`
  of the same camera on the same image.
- World export: colour Worlds, Environment Texture images, and clear errors otherwise.
- The bake with Environment Glow: World pixels get Transmittance e^(-density x distance) and
  the glow, which agrees with the direct convolution by the exact PSF (the reference).
"""
import math

import bpy
import numpy as np
import pytest

from airlight import bake, environment, native
from conftest import build_plane_scene, read_exr


def _uv_image(width=64, height=32):
    """A float image whose red/green hold the (u, v) of each texel centre (v = 1 at the top)."""
    image = bpy.data.images.new("UV", width, height, alpha=False, float_buffer=True)
    image.colorspace_settings.name = 'Non-Color'  # before the pixels: it reloads the buffer
    u = (np.arange(width) + 0.5) / width
    v = (np.arange(height) + 0.5) / height  # Blender rows start at the bottom
    px = np.zeros((height, width, 4), dtype=np.float32)
    px[..., 0] = u[None, :]
    px[..., 1] = v[:, None]
    px[..., 3] = 1.0
    image.pixels.foreach_set(px.ravel())
    return image


def _env_world(image, strength=1.0):
    world = bpy.data.worlds.new("Env")
    world.use_nodes = True
    nodes, links = world.node_tree.nodes, world.node_tree.links
    tex = nodes.new('ShaderNodeTexEnvironment')
    tex.image = image
    tex.interpolation = 'Linear'
    background = nodes['Background']
    background.inputs['Strength'].default_value = strength
    links.new(tex.outputs['Color'], background.inputs['Color'])
    return world


def test01_native_equirect_mapping_is_blenders(tmp_path):
    scene = build_plane_scene(tmp_path, fog=False, light=False, size=(24, 16))
    bpy.data.objects.remove(bpy.data.objects["Ground"])
    image = _uv_image()
    scene.world = _env_world(image)
    scene.render.engine = 'CYCLES'
    scene.cycles.samples = 1
    scene.cycles.use_denoising = False
    scene.cycles.pixel_filter_type = 'BOX'
    scene.cycles.filter_width = 0.01
    scene.view_settings.view_transform = 'Standard'
    scene.render.image_settings.file_format = 'OPEN_EXR'
    scene.render.image_settings.color_depth = '32'
    cam = scene.camera
    cam.data.lens = 50.0
    module = native.get()
    world = environment.world_map(scene, max_width=64)
    assert world.shape == (32, 64, 3)
    checked = 0
    for rx, rz in ((1.2, 0.3), (1.57, 2.0), (0.4, -1.0), (2.6, 4.0)):
        cam.rotation_euler = (rx, 0.0, rz)
        bpy.context.view_layer.update()
        path = str(tmp_path / f"uv_{rx}_{rz}.exr")
        scene.render.filepath = path
        bpy.ops.render.render(write_still=True)
        pixels, names = read_exr(path)
        cycles_uv = pixels[..., [names.index("R"), names.index("G")]]
        depsgraph = bpy.context.evaluated_depsgraph_get()
        from airlight import scene_description
        width, height, cam_to_world, projection = scene_description.export_camera(scene, depsgraph)
        ours = module.environment_view(cam_to_world=cam_to_world, projection=projection, width=width,
                                       height=height, glow=world)[..., :2]
        # Away from the u seam (where bilinear lookups blend 0 and 1), the two agree to a
        # fraction of a texel.
        ok = (cycles_uv[..., 0] > 0.05) & (cycles_uv[..., 0] < 0.95)
        assert ok.sum() > 100
        diff = np.abs(ours[ok] - cycles_uv[ok])
        assert diff[:, 0].max() < 0.5 / 64 and diff[:, 1].max() < 0.5 / 32, (rx, rz, diff.max(axis=0))
        checked += int(ok.sum())
    assert checked > 800


def test02_world_map_sources_and_errors(tmp_path):
    scene = build_plane_scene(tmp_path, fog=True)
    scene.world = None
    assert environment.world_map(scene) is None
    world = bpy.data.worlds.new("Flat")
    world.use_nodes = False
    world.color = (0.1, 0.2, 0.3)
    scene.world = world
    flat = environment.world_map(scene)
    np.testing.assert_allclose(flat[3, 5], (0.1, 0.2, 0.3), rtol=1e-6)
    world.use_nodes = True
    world.node_tree.nodes['Background'].inputs['Color'].default_value = (1.0, 0.5, 0.25, 1.0)
    world.node_tree.nodes['Background'].inputs['Strength'].default_value = 2.0
    np.testing.assert_allclose(environment.world_map(scene)[0, 0], (2.0, 1.0, 0.5), rtol=1e-6)
    # A big image is box-filtered down, its mean kept.
    image = bpy.data.images.new("Big", 1024, 512, float_buffer=True)
    rng = np.random.default_rng(1)
    px = rng.random((512, 1024, 4), dtype=np.float32)
    image.pixels.foreach_set(px.ravel())
    scene.world = _env_world(image, strength=3.0)
    big = environment.world_map(scene)
    assert big.shape == (128, 256, 3)
    np.testing.assert_allclose(big.mean(axis=(0, 1)), 3.0 * px[..., :3].mean(axis=(0, 1)), rtol=1e-4)
    # Top row of the map is the top of the image (Blender stores rows bottom-up).
    np.testing.assert_allclose(big[0, 0], 3.0 * px[-4:, :4, :3].mean(axis=(0, 1)), rtol=1e-4)
    # Unsupported shaders: a clear error, in the bake too.
    sky = scene.world.node_tree.nodes.new('ShaderNodeTexSky')
    scene.world.node_tree.links.new(sky.outputs['Color'],
                                    scene.world.node_tree.nodes['Background'].inputs['Color'])
    with pytest.raises(environment.WorldMapError, match="Environment Texture only"):
        environment.world_map(scene)
    scene.airlight.environment_glow = False
    assert environment.prepare(scene) is None  # off: the World is not read at all
    scene.airlight.environment_glow = True
    with pytest.raises(bake.BakeError, match="Sky Texture"):
        bake.prepare(scene, bpy.context.evaluated_depsgraph_get())
    if native.available():
        with pytest.raises(RuntimeError, match="Sky Texture"):  # the operator's error report
            bpy.ops.airlight.bake()


def test03_bake_with_glow_matches_exact_psf_reference(tmp_path):
    """World pixels: T = e^(-sigma D) and the glow against the direct convolution of the
    World with the exact PSF (Sun 2005 eq. 20; no factorisation, no SH truncation)."""
    scene = build_plane_scene(tmp_path, fog=True, light=False, size=(48, 32))
    scene.camera.rotation_euler = (math.radians(75.0), 0.0, 0.0)  # horizon across the frame
    # A smooth sky with a broad bright patch ahead of the camera (+Y).
    h, w = 32, 64
    v = 1.0 - (np.arange(h) + 0.5) / h
    u = (np.arange(w) + 0.5) / w
    theta = (1.0 - v)[:, None] * math.pi
    phi = (0.5 - u)[None, :] * 2.0 * math.pi
    d = np.stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta) + 0 * phi], -1)
    sun = np.exp(6.0 * (d @ np.array([0.0, 0.8, 0.6]) - 1.0))
    sky = 0.2 + 0.1 * np.clip(d[..., 2], 0, 1) + 2.0 * sun
    px = np.ones((h, w, 4), dtype=np.float32)
    px[..., :3] = sky[..., None] * np.array([1.0, 0.9, 0.8])
    image = bpy.data.images.new("Sky", w, h, float_buffer=True)
    image.pixels.foreach_set(px[::-1].ravel())
    scene.world = _env_world(image)
    settings = scene.airlight
    settings.density = 0.02
    settings.environment_glow = True
    settings.environment_distance = 60.0
    settings.environment_sh_order = 24
    settings.color = (0.9, 0.9, 0.9)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    description, bake_kw = bake.prepare(scene, depsgraph)
    assert bake_kw.get("environment") is not None
    path = str(tmp_path / "glow.exr")
    stats, _ = bake.run(description, bake_kw, path)
    assert stats["seconds_environment"] > 0.0
    pixels, names = read_exr(path)
    A = pixels[..., [names.index(f"Fog.Airlight.{c}") for c in "RGB"]]
    T = pixels[..., [names.index(f"Fog.Transmittance.{c}") for c in "RGB"]]
    module = native.get()
    off_kw = dict(bake_kw, environment=None)
    plain = module.bake(**description, **bake.native_settings(off_kw))
    miss = ~np.isfinite(plain["depth"])
    assert 100 < miss.sum() < miss.size - 100  # sky and ground both in frame
    np.testing.assert_allclose(T[miss], math.exp(-0.02 * 60.0), rtol=1e-6)
    np.testing.assert_allclose(T[~miss], plain["transmittance"][~miss], rtol=1e-6)
    glow = (A - plain["airlight"])[miss]
    world = environment.world_map(scene, max_width=32)
    ref_map = module.environment_fog(world=world, sigma_t=0.02, distance=60.0, albedo=[0.9, 0.9, 0.9],
                                     sh_order=-1, out_width=32, out_height=16)["glow"]
    ref = module.environment_view(cam_to_world=description["cam_to_world"],
                                  projection=description["projection"], width=48, height=32,
                                  glow=ref_map)[miss]
    rel = np.abs(glow - ref) / ref
    print(f"environment glow (SH 24, exact-PSF eigenvalues) vs exact-PSF direct convolution: "
          f"mean {100 * rel.mean():.2f} %, p99 {100 * np.percentile(rel, 99):.2f} %")
    assert rel.mean() < 0.05
    # And without the glow nothing changes on surfaces or in the sky's airlight.
    np.testing.assert_allclose(A[~miss], plain["airlight"][~miss], rtol=1e-6)


def _psf_lambda0_scipy(Tsv):
    """lambda_0 = 2 pi int_0^pi PSF(gamma) sin(gamma) dgamma with Sun 2005's eq. 20 PSF and F
    by scipy quadrature (independent of the native kernels)."""
    from scipy.integrate import quad

    def F(u, v):
        return quad(lambda x: math.exp(-u * math.tan(x)) if x < math.pi / 2 else 0.0, 0.0, v, limit=200)[0]

    def integrand(g):
        s = math.sin(g)
        psf = Tsv * math.exp(-Tsv * math.cos(g)) * (F(Tsv * s, math.pi / 2) - F(Tsv * s, g / 2)) / (2 * math.pi * s)
        return psf * s

    return 2 * math.pi * quad(integrand, 1e-9, math.pi, limit=200, points=[0.01, 0.1, 1.0])[0]


def test04_world_light_on_surfaces_through_fog(tmp_path):
    """Surface shading + Environment Glow: the World goes in its own light group and the bake
    writes its correction pass E_fogged / E_world - 1 per pixel (eq. 26-27 irradiance). For a
    constant World that is e^-T + albedo lambda_0 - 1 on every surface, lambda_0 from an
    independent scipy quadrature of the PSF."""
    from airlight import surface
    scene = build_plane_scene(tmp_path, fog=True, light=False, size=(40, 30))
    scene.render.engine = 'CYCLES'
    scene.camera.rotation_euler = (math.radians(70.0), 0.0, 0.0)
    world = bpy.data.worlds.new("Sky")
    world.use_nodes = True
    world.node_tree.nodes['Background'].inputs['Color'].default_value = (0.5, 0.6, 0.8, 1.0)
    scene.world = world
    settings = scene.airlight
    settings.density = 0.05
    settings.color = (0.8, 0.8, 0.8)
    settings.surface_shading = True
    settings.environment_glow = True
    settings.environment_distance = 30.0
    depsgraph = bpy.context.evaluated_depsgraph_get()
    description, bake_kw = bake.prepare(scene, depsgraph)
    assert bake_kw["environment"]["group"] == surface.WORLD_GROUP
    assert world.lightgroup == surface.WORLD_GROUP
    assert surface.WORLD_GROUP in {lg.name for lg in scene.view_layers[0].lightgroups}
    path = str(tmp_path / "world_surface.exr")
    bake.run(description, bake_kw, path)
    pixels, names = read_exr(path)
    ratio = pixels[..., [names.index(f"Fog.Surface_{surface.WORLD_GROUP}.{c}") for c in "RGB"]]
    depth = native.get().bake(**description, **bake.native_settings(bake_kw))["depth"]
    floor = np.isfinite(depth)
    assert 100 < floor.sum() < floor.size - 50
    T = 0.05 * 30.0
    want = math.exp(-T) + 0.8 * _psf_lambda0_scipy(T) - 1.0
    print(f"world surface ratio - 1: {ratio[floor].mean():.5f} (want {want:.5f})")
    np.testing.assert_allclose(ratio[floor], want, rtol=2e-3, atol=2e-4)
    np.testing.assert_array_equal(ratio[~floor], 0.0)
    # The compositor multiplies the World's light-group pass by it (the operator's bake
    # syncs the compositor, as F12 does).
    assert bpy.ops.airlight.bake('EXEC_DEFAULT', filepath=path) == {'FINISHED'}
    links = [(l.from_socket.name, l.to_node.name) for l in scene.node_tree.links]
    assert any(name == f"Combined_{surface.WORLD_GROUP}" for name, _ in links), links
    assert any(name == f"Surface_{surface.WORLD_GROUP}" for name, _ in links), links
    # Off: no group wanted, no pass.
    settings.environment_glow = False
    assert surface.ensure_world_group(scene) is None


def _pixel_rays(scene):
    """Origin and unit directions (H, W, 3) of the pixel-centre rays of the scene camera, from
    Blender's own view frame (row 0 = top), independent of the native camera code."""
    cam = scene.camera
    W, H = scene.render.resolution_x, scene.render.resolution_y
    tr, br, bl, tl = (np.array(v) for v in cam.data.view_frame(scene=scene))
    x = (np.arange(W) + 0.5) / W
    y = (np.arange(H) + 0.5) / H
    local = tl[None, None, :] + (tr - tl)[None, None, :] * x[None, :, None] + (bl - tl)[None, None, :] * y[:, None, None]
    R = np.array(cam.matrix_world.to_3x3())
    d = local @ R.T
    return np.array(cam.matrix_world.translation), d / np.linalg.norm(d, axis=-1, keepdims=True)


def test05_world_light_with_fog_object(tmp_path):
    """Environment Glow + surface shading + a fog object (Fogshop section 4.2): the World's
    surface ratio uses each pixel's average optical depth Tbar(p) = sigma D + sum_i c_i / a_i
    T(a_i |p - b_i|), T(u) = sqrt(pi)/2 dawsn(u)/u (scipy), so it dips where the Gaussian
    sits on the floor; World pixels keep the Gaussians' optical depth in their transmittance
    and the glow is dimmed by it (erf line integral, computed here)."""
    from scipy.special import dawsn, erfc

    from airlight import fog_object, surface
    scene = build_plane_scene(tmp_path, fog=True, light=False, size=(40, 30))
    scene.render.engine = 'CYCLES'
    scene.camera.rotation_euler = (math.radians(80.0), 0.0, 0.0)  # floor and sky in frame
    world = bpy.data.worlds.new("Sky")
    world.use_nodes = True
    world.node_tree.nodes['Background'].inputs['Color'].default_value = (0.5, 0.6, 0.8, 1.0)
    scene.world = world
    settings = scene.airlight
    sigma, D, albedo = 0.05, 30.0, 0.8
    settings.density = sigma
    settings.color = (albedo,) * 3
    settings.surface_shading = True
    settings.environment_glow = True
    settings.environment_distance = D
    # One Gaussian on the floor ahead, one in front of the sky.
    b = np.array([[0.0, 9.0, 0.3], [1.0, 20.0, 2.0 + 20.0 * math.tan(math.radians(4.0))]])
    a = np.array([0.8, 0.5])
    c = np.array([1.0, 0.4])
    fog_object.new_fog_object("Fog", scene.collection, b, a, c)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    description, bake_kw = bake.prepare(scene, depsgraph)
    assert len(description["rbf_scales"]) == 2 and bake_kw["environment"]["group"] == surface.WORLD_GROUP
    path = str(tmp_path / "world_fog_object.exr")
    bake.run(description, bake_kw, path)
    pixels, names = read_exr(path)
    ratio = pixels[..., [names.index(f"Fog.Surface_{surface.WORLD_GROUP}.{c}") for c in "RGB"]]
    A = pixels[..., [names.index(f"Fog.Airlight.{c}") for c in "RGB"]]
    Tr = pixels[..., [names.index(f"Fog.Transmittance.{c}") for c in "RGB"]]

    origin, d = _pixel_rays(scene)
    with np.errstate(divide="ignore"):
        t_floor = np.where(d[..., 2] < -1e-6, -origin[2] / d[..., 2], np.inf)
    hit = origin + d * np.where(np.isfinite(t_floor), t_floor, 0.0)[..., None]
    floor = np.isfinite(t_floor) & (np.abs(hit[..., 0]) < 50.0) & (np.abs(hit[..., 1]) < 50.0)  # the plane
    sky = ~floor
    assert 100 < floor.sum() and sky.sum() > 50
    # Surfaces: Tbar at the floor hit, then e^-Tbar + albedo lambda_0(Tbar) - 1 (a constant
    # World has band 0 only; lambda_0 interpolated between exact eigenvalues).
    p = hit[floor]
    u = a[None, :] * np.linalg.norm(p[:, None, :] - b[None, :, :], axis=-1)
    Tbar = sigma * D + np.sum(c / a * 0.5 * np.sqrt(np.pi) * dawsn(u) / u, axis=1)
    grid = np.linspace(Tbar.min(), Tbar.max(), 41)
    lam0 = np.array([native.get().psf_eigenvalues(t, 0, "exact")[0] for t in grid])
    want = np.exp(-Tbar) + albedo * np.interp(Tbar, grid, lam0) - 1.0
    got = ratio[floor]
    print(f"world surface ratio with a fog object: {got[:, 0].min():.4f} .. {got[:, 0].max():.4f}, "
          f"max |error| {np.abs(got[:, 0] - want).max():.2e}")
    np.testing.assert_allclose(got, np.repeat(want[:, None], 3, axis=1), atol=2e-3)
    assert got[:, 0].max() - got[:, 0].min() > 0.05  # it changes where the fog object is
    # World pixels: e^(-sigma D) times the Gaussians along the ray from the near plane.
    ds = d[sky]
    t0 = scene.camera.data.clip_start / (ds @ -np.array(scene.camera.matrix_world.to_3x3())[:, 2])
    Tg = np.zeros(len(ds))
    for bi, ai, ci in zip(b, a, c):
        ts = (bi - origin) @ ds.T
        h2 = np.sum((bi - origin) ** 2) - ts ** 2
        Tg += ci * np.sqrt(np.pi) / (2 * ai) * np.exp(-ai * ai * h2) * erfc(ai * (t0 - ts))
    assert Tg.max() > 0.3  # the second Gaussian is in front of the sky
    np.testing.assert_allclose(Tr[sky], np.repeat((math.exp(-sigma * D) * np.exp(-Tg))[:, None], 3, axis=1),
                               rtol=1e-4, atol=1e-6)
    # The glow seen there is the homogeneous one dimmed by the same factor (no lights: the bake
    # itself adds no airlight).
    fog = native.get().environment_fog(
        world=environment.world_map(scene), sigma_t=sigma, distance=D, albedo=[albedo] * 3,
        sh_order=settings.environment_sh_order, out_width=256, out_height=128, kind="exact")
    glow = native.get().environment_view(cam_to_world=description["cam_to_world"],
                                         projection=description["projection"], width=40, height=30,
                                         glow=fog["glow"])[sky]
    np.testing.assert_allclose(A[sky], glow * np.exp(-Tg)[:, None], rtol=1e-4, atol=1e-7)
