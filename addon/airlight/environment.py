"""The World seen through the fog (Sun et al. 2005, section 6.4): glows around the bright
parts of an HDRI or sky colour, and the World dimmed by the fog between the camera and it.

Data flow: the World's shader (Background colour, or an Environment Texture image) ->
`world_map()` (an equirectangular numpy array, gathered in the main thread) -> the native
`environment_fog` (spherical-harmonic convolution with the airlight point-spread function,
eq. 25; the PSF's eigenvalues from the exact eq. 20 for the fog's optical distance, ~0.1 s,
rather than the paper's empirical NPSF factorisation, eq. 22, whose error the native tests
measure) and `environment_view` (the glow along every camera ray) -> added to the Airlight
pass where the camera sees the World, whose Transmittance becomes e^(-density x distance)
(eq. 26-27). The compositor's `render x T + A` then shows the World through the fog.

With fog objects (Gaussians in the scene description), `environment_rbf_view` adds per
pixel (a) the Gaussians' optical depth along each ray that sees the World, which multiplies
the World's transmittance and dims the glow (the glow is the homogeneous fog's, seen through
the Gaussians in front; the Gaussians' own scattering of the World's light is not added),
and (b) Fogshop's average optical depth Tbar(p) = density x distance + sum_i Tbar_i(p)
(section 4.2) at every surface, which replaces the homogeneous optical depth in the
World's light on that surface (`environment_irradiance_varying`). Tbar leaves out the fog
objects' noise (Fogshop 5.5) and their own colours: the glow's albedo is the fog colour.

The model assumes the World's light comes from sources all at one distance (the
"Environment Distance" setting): without a distance, fog that fills all space would hide
the World completely, which is what Cycles renders for a World volume.
"""

import numpy as np

# Largest width of the map handed to the spherical-harmonic projection: bands up to ~64
# need ~128 columns; more only costs time.
MAX_MAP_WIDTH = 256
# Relative error allowed in Fogshop's average optical depth Tbar(p) (the far field's
# bound, environment.h): 1e-2 of Tbar is at most 1e-2 Tbar relative in e^-Tbar; the
# measured error is 20-150x below the bound (benchmarks/bench_rbf_environment.py).
AVERAGE_DEPTH_TOLERANCE = 1e-2


class WorldMapError(ValueError):
    """The World cannot be turned into an environment map; the message says why."""


def _srgb_to_linear(c):
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4).astype(np.float32)


def _downsample(pixels, max_width):
    """Box-filters an (H, W, 3) map down by an integer factor until W <= max_width."""
    h, w, _ = pixels.shape
    f = 1
    while w // f > max_width and h // (2 * f) >= 1:
        f *= 2
    if f == 1:
        return pixels
    h2, w2 = h // f, w // f
    return pixels[:h2 * f, :w2 * f].reshape(h2, f, w2, f, 3).mean(axis=(1, 3)).astype(np.float32)


def _image_pixels(image):
    """(H, W, 3) float32 linear RGB, row 0 = top, of a Blender image."""
    w, h = image.size
    if w == 0 or h == 0:
        raise WorldMapError(f"Environment image '{image.name}' has no pixels (missing file?).")
    channels = image.channels
    flat = np.empty(w * h * channels, dtype=np.float32)
    image.pixels.foreach_get(flat)
    pixels = flat.reshape(h, w, channels)[::-1, :, :3]  # Blender's rows start at the bottom
    if channels < 3:
        pixels = np.repeat(flat.reshape(h, w, channels)[::-1, :, :1], 3, axis=2)
    # Byte images hold display-encoded values; float images are linear already.
    if not image.is_float and image.colorspace_settings.name == 'sRGB':
        pixels = _srgb_to_linear(pixels)
    pixels = np.ascontiguousarray(pixels, dtype=np.float32)
    if not np.all(np.isfinite(pixels)):
        raise WorldMapError(f"Environment image '{image.name}' holds NaN or infinite pixels.")
    return np.maximum(pixels, 0.0)


def _constant_map(color, strength):
    rgb = np.asarray(color[:3], dtype=np.float32) * np.float32(strength)
    return np.ascontiguousarray(np.broadcast_to(rgb, (8, 16, 3)), dtype=np.float32)


def world_source(scene):
    """What the World emits, read from its nodes without touching pixels (cheap enough for
    panel drawing): None (nothing), ('COLOR', rgb) or ('IMAGE', image, strength).

    Supported: no World (None), a World without nodes (its colour), and node Worlds whose
    active output's Surface is a Background shader with an unlinked Color, or a Color linked
    straight from an equirectangular Environment Texture (no Vector input). Anything else
    raises WorldMapError naming the node to change.
    """
    world = scene.world
    if world is None:
        return None
    if not world.use_nodes or world.node_tree is None:
        return ('COLOR', tuple(world.color))
    tree = world.node_tree
    outputs = [n for n in tree.nodes if n.bl_idname == 'ShaderNodeOutputWorld' and n.is_active_output]
    outputs = outputs or [n for n in tree.nodes if n.bl_idname == 'ShaderNodeOutputWorld']
    if not outputs or not outputs[0].inputs['Surface'].is_linked:
        return None
    shader = outputs[0].inputs['Surface'].links[0].from_node
    if shader.bl_idname != 'ShaderNodeBackground':
        raise WorldMapError(
            f"World '{world.name}': the environment glow reads a Background shader, not "
            f"'{shader.name}' ({shader.bl_idname}). Connect a Background node to the World Output, "
            "or turn Environment Glow off.")
    color_in, strength_in = shader.inputs['Color'], shader.inputs['Strength']
    if strength_in.is_linked:
        raise WorldMapError(f"World '{world.name}': the Background Strength must not be linked "
                            "for the environment glow.")
    strength = float(strength_in.default_value)
    if not color_in.is_linked:
        return ('COLOR', tuple(strength * c for c in color_in.default_value[:3]))
    tex = color_in.links[0].from_node
    if tex.bl_idname != 'ShaderNodeTexEnvironment':
        raise WorldMapError(
            f"World '{world.name}': the Background Color comes from '{tex.name}' ({tex.bl_idname}); the "
            "environment glow reads a constant colour or an Environment Texture only.")
    if tex.image is None:
        raise WorldMapError(f"World '{world.name}': Environment Texture '{tex.name}' has no image.")
    if tex.projection != 'EQUIRECTANGULAR':
        raise WorldMapError(f"World '{world.name}': Environment Texture '{tex.name}' uses "
                            f"{tex.projection} projection; the environment glow reads equirectangular maps.")
    if tex.inputs['Vector'].is_linked:
        raise WorldMapError(f"World '{world.name}': Environment Texture '{tex.name}' has a linked Vector "
                            "(mapping); the environment glow reads the default mapping only.")
    return ('IMAGE', tex.image, strength)


def world_map(scene, max_width=MAX_MAP_WIDTH):
    """The scene's World as an equirectangular (H, W, 3) float32 array (Blender's Environment
    Texture mapping, row 0 = top), or None when the World emits nothing (see world_source)."""
    source = world_source(scene)
    if source is None:
        return None
    if source[0] == 'COLOR':
        return _constant_map(source[1], 1.0)
    _, image, strength = source
    return _downsample(_image_pixels(image), max_width) * np.float32(strength)


def prepare(scene):
    """What the worker needs (main thread, touches bpy): None when the glow is off or the
    World is black, else a dict of plain data."""
    settings = scene.airlight
    if not settings.environment_glow:
        return None
    world = world_map(scene)
    if world is None or not np.any(world > 0.0):
        return None
    return dict(world=world, distance=float(settings.environment_distance),
                sh_order=int(settings.environment_sh_order))


def apply(module, environment, description, result):
    """Adds the World's glow to the bake result (no bpy: runs in the bake's worker thread).

    Where the pixel-centre ray misses every surface (depth inf), the Airlight pass gains the
    glow seen along that ray and the Transmittance becomes e^(-density x distance). Returns
    the seconds spent.
    """
    import time
    start = time.perf_counter()
    sigma_t = float(description["sigma_t"])
    fog = module.environment_fog(
        world=environment["world"], sigma_t=sigma_t, distance=environment["distance"],
        albedo=np.asarray(description["albedo"], dtype=np.float64), sh_order=environment["sh_order"],
        out_width=256, out_height=128, kind="exact")
    glow = module.environment_view(
        cam_to_world=description["cam_to_world"], projection=description["projection"],
        width=int(description["width"]), height=int(description["height"]), glow=fog["glow"])
    miss = ~np.isfinite(result["depth"])
    group = environment.get("group")
    shading = group is not None and "surface_normals" in result
    rbf = gaussian_view(module, environment, description, result, average=shading)
    if rbf is None:
        result["airlight"][miss] += glow[miss]
        result["transmittance"][miss] = np.float32(fog["transmittance"])
    else:
        # The Gaussians between the camera and the World dim both (the bake's own
        # transmittance there is 0 with a background density: fog to infinity).
        dim = np.exp(-rbf["world_optical_depth"][miss]).astype(np.float32)[:, None]
        result["airlight"][miss] += glow[miss] * dim
        result["transmittance"][miss] = np.float32(fog["transmittance"]) * dim
    if shading:
        depth = None if rbf is None else rbf["average_depth"]
        result["environment_surface"] = (group, surface_ratio(module, fog, description, result, depth))
    return time.perf_counter() - start


def has_gaussians(description):
    """True when the scene description carries fog objects' Gaussians (scene_export)."""
    scales = description.get("rbf_scales")
    return scales is not None and len(scales) > 0


def gaussian_view(module, environment, description, result, average=True):
    """None without fog objects; else `environment_rbf_view`'s per-pixel arrays for the
    bake's camera: world_optical_depth (the Gaussians along rays that see the World) and,
    with `average`, average_depth (Tbar at each pixel's first hit, Fogshop eq. 26)."""
    if not has_gaussians(description):
        return None
    return module.environment_rbf_view(
        cam_to_world=description["cam_to_world"], projection=description["projection"],
        width=int(description["width"]), height=int(description["height"]),
        clip_start=float(description.get("clip_start", 0.0)),
        clip_end=float(description.get("clip_end", np.inf)),
        depth=np.ascontiguousarray(result["depth"], dtype=np.float32),
        centres=description["rbf_centres"], scales=description["rbf_scales"],
        amplitudes=description["rbf_amplitudes"], beta0=float(description["sigma_t"]),
        distance=float(environment["distance"]), tolerance=AVERAGE_DEPTH_TOLERANCE, average=average)


def surface_ratio(module, fog, description, result, average_depth=None):
    """(H, W, 3) float32: E_fogged(n) / E_world(n) - 1 per pixel, the correction the
    compositor multiplies the World's light-group pass by (surface.py): the irradiance the
    World gives a surface of normal n through the fog (attenuated World plus its airlight,
    eq. 26-27, spherical-harmonic bands l <= 2) over the fog-free one. 0 where no surface
    (normal 0) or where the World gives that normal (almost) no light, whose pass is ~0
    anyway. With `average_depth` ((H, W): Fogshop's Tbar per pixel, fog objects present)
    each surface gets the PSF of its own optical depth (Fogshop eq. 27); without, every
    surface gets the homogeneous density x distance (unchanged)."""
    normals = result["surface_normals"].reshape(-1, 3)
    hit = np.any(normals != 0.0, axis=1)
    ratio = np.zeros_like(normals, dtype=np.float32)
    if hit.any():
        albedo = np.asarray(description["albedo"], dtype=np.float64)
        if average_depth is None:
            e_world, e_fogged = module.environment_irradiance(
                fog["sh_world"], fog["eigenvalues"], fog["transmittance"], albedo,
                normals[hit].astype(np.float64))
        else:
            e_world, e_fogged = module.environment_irradiance_varying(
                fog["sh_world"], albedo, normals[hit].astype(np.float64),
                np.asarray(average_depth, dtype=np.float64).reshape(-1)[hit])
        floor = 1e-6 * max(float(e_world.max()), 1e-30)
        lit = e_world > floor
        r = np.zeros_like(e_world)
        r[lit] = e_fogged[lit] / e_world[lit] - 1.0
        ratio[hit] = r.astype(np.float32)
    return ratio.reshape(result["surface_normals"].shape)
