"""Fog settings stored in the .blend: `scene.airlight` and `light.airlight`."""

import bpy
from bpy.props import (BoolProperty, EnumProperty, FloatProperty, FloatVectorProperty,
                       IntProperty, PointerProperty, StringProperty)

from . import compositor


def _on_fog_changed(self, context):
    """Keeps the compositor fog nodes muted or live when the fog is switched."""
    scene = context.scene if context else None
    if scene is not None and getattr(scene, "airlight", None) is not None:
        compositor.sync(scene)


def _on_surface_changed(self, context):
    """Rebuilds the compositor's surface-shading chain (and its passes) when Surface Shading
    or Environment Glow (the World's light group) is switched, so the next render composites
    with it (a render reads the node links as they are when it starts); the Image node gets
    neutral passes with the right names until the next bake."""
    scene = context.scene if context else None
    if scene is not None and getattr(scene, "airlight", None) is not None and compositor.is_set_up(scene):
        try:
            compositor.setup(scene, compositor.neutral_passes(scene))
        except Exception as ex:  # an update callback must not raise into the UI
            print(f"Airlight: cannot update the compositor: {ex}", flush=True)


class AirlightSceneSettings(bpy.types.PropertyGroup):
    enabled: BoolProperty(
        name="Fog",
        description="Add analytic single-scattering fog to renders of this scene "
                    "(bakes the fog passes before each frame and composites them)",
        default=False,
        update=_on_fog_changed,
    )
    density: FloatProperty(
        name="Density",
        description="Extinction coefficient sigma_t of the fog, per scene unit "
                    "(the bake works in Blender units, scale_length is not applied)",
        default=0.05, min=0.0, soft_max=1.0, max=1.0e4,
        step=1, precision=4,
    )
    color: FloatVectorProperty(
        name="Color",
        description="Single-scattering albedo of the fog: the fraction of extinguished "
                    "light that is scattered, per colour channel",
        subtype='COLOR', size=3, default=(1.0, 1.0, 1.0), min=0.0, max=1.0,
    )
    model: EnumProperty(
        name="Model",
        description="Which airlight model computes the fog",
        items=(
            ('AUTO', "Automatic", "The cheapest model whose measured error meets the Accuracy target"),
            ('SUN05', "Sun 2005 (table)", "Sun et al. 2005 analytic airlight with a tabulated special function F"),
            ('SUN05_EXACT', "Sun 2005 (exact)", "Sun et al. 2005 analytic airlight with F evaluated exactly"),
            ('QUADRATURE', "Quadrature", "Numerical integration along each view ray, any phase "
                                         "function: slow, the reference"),
            ('BIRI06', "Biri 2006 (any phase)", "Biri et al. 2006 analytic airlight with a table per phase "
                                                "function: handles anisotropic fog"),
            ('BASELINE', "Baseline (constant colour)",
             "What Blender's Mist pass does: one fog colour for the whole image, "
             "C (1 - transmittance), with C fitted to the physical fog. No light shapes; "
             "the bar the other models beat"),
            ('PEGORARO10', "Pegoraro 2010 (closed form)", "Pegoraro et al. 2010 exact closed form with the "
                                                          "phase function as a Legendre polynomial: any phase, "
                                                          "no table"),
            ('HOFFMAN02', "Hoffman-Preetham 2002 (daylight)",
             "Hoffman & Preetham 2002 daylight haze: sun lamps only, in Rayleigh scattering "
             "(Rayleigh Density, bluer with 1/wavelength^4) plus Mie haze (Density, Anisotropy); "
             "per-colour extinction. Point and spot lights are left out of the fog"),
        ),
        default='AUTO',
    )
    phase: EnumProperty(
        name="Phase",
        description="Phase function of the fog: how much light it scatters in each direction "
                    "(the Sun 2005 models handle only isotropic fog, Henyey-Greenstein with "
                    "Anisotropy 0)",
        items=(
            ('HENYEY_GREENSTEIN', "Henyey-Greenstein",
             "Henyey-Greenstein lobe set by Anisotropy, as Cycles' Volume Scatter node "
             "(Anisotropy 0 is isotropic)"),
            ('RAYLEIGH', "Rayleigh", "Rayleigh scattering by particles much smaller than the "
                                     "wavelength (clear air): 3 (1 + cos^2) / (16 pi)"),
            ('MIE_HAZY', "Mie (hazy)", "Nishita's hazy-atmosphere Mie approximation: a mild forward lobe"),
            ('MIE_MURKY', "Mie (murky)", "Nishita's murky-atmosphere Mie approximation: a sharp forward lobe"),
        ),
        default='HENYEY_GREENSTEIN',
    )
    anisotropy: FloatProperty(
        name="Anisotropy",
        description="Henyey-Greenstein g, Blender's sign: positive is forward scattering "
                    "(light glows around lights seen through the fog), negative is back "
                    "scattering, 0 is isotropic",
        default=0.0, min=-0.99, max=0.99, step=1, precision=3,
    )
    use_fog_top: BoolProperty(
        name="Fog Top",
        description="Bound the fog above at the Top height for sun lamps: sunlight then "
                    "crosses the fog from the top down and fades with depth, as in a "
                    "Cycles volume slab. Off: sunlight reaches all the fog unattenuated "
                    "(Hoffman-Preetham), a fair approximation near the ground only",
        default=True,
    )
    fog_top: FloatProperty(
        name="Top",
        description="World Z height of the top of the fog layer that sun lamps shine "
                    "through (used when Fog Top is on; point and spot lights and the "
                    "transmittance treat the fog as unbounded)",
        default=10.0, soft_min=-1000.0, soft_max=1000.0,
        subtype='DISTANCE', unit='LENGTH',
    )
    # Fog-object noise (Fogshop section 5.5): perturbs each Gaussian's optical depth along
    # the view rays with world-space gradient noise. Keyframe these to animate it.
    noise_amplitude: FloatProperty(
        name="Noise Amplitude",
        description="Strength of the noise that breaks up fog objects (0 turns it off): "
                    "how far each fog blob's view rays are bent, relative to the blob's size "
                    "as seen from the camera. Perspective cameras only",
        default=0.0, min=0.0, soft_max=2.0, max=100.0, step=1, precision=3,
    )
    noise_scale: FloatProperty(
        name="Noise Scale",
        description="Size of the noise features in scene units (world space, so the noise "
                    "stays put when the camera moves)",
        default=1.0, min=1.0e-4, soft_min=0.01, soft_max=100.0, max=1.0e6,
        step=10, precision=3, subtype='DISTANCE',
    )
    noise_offset: FloatVectorProperty(
        name="Noise Offset",
        description="Shift of the noise pattern, in multiples of Noise Scale: keyframe it "
                    "to make the fog objects' noise drift over time",
        size=3, default=(0.0, 0.0, 0.0), subtype='XYZ',
    )
    accuracy: FloatProperty(
        name="Accuracy",
        description="Largest relative error of the fog you accept, in percent: the "
                    "Automatic model picks the cheapest model whose measured error is below it",
        default=1.0, min=0.01, max=100.0, soft_min=0.1, soft_max=10.0,
        subtype='PERCENTAGE',
    )
    table_resolution: EnumProperty(
        name="Table Size",
        description="Samples per axis of the Sun 2005 special-function table: larger is "
                    "more accurate and costs a little more memory and a one-off build "
                    "(the expected error shown below follows it)",
        items=(
            ('64', "64", "64 x 64 samples: coarsest"),
            ('128', "128", "128 x 128 samples"),
            ('256', "256", "256 x 256 samples (default)"),
            ('512', "512", "512 x 512 samples: finest"),
        ),
        default='256',
    )
    table_interpolation: EnumProperty(
        name="Table Lookup",
        description="How the Sun 2005 table is read between its samples",
        items=(
            ('BILINEAR', "Bilinear", "Blend the four nearest samples: accurate (default)"),
            ('NEAREST', "Nearest", "Take the nearest sample: about 20 times the error of "
                                   "bilinear at the same size, no faster in the bake"),
        ),
        default='BILINEAR',
    )
    gaussian_resolution: EnumProperty(
        name="Fog Object Resolution",
        description="Where the bake evaluates fog objects (Gaussian fog): blobs wholly in front "
                    "of the surfaces are computed every 1, 2 or 4 pixels and blended in between; "
                    "blobs a surface cuts stay exact per pixel (per sub-sample on depth edges). With Automatic "
                    "a finer setting is used when the accuracy target asks for it. Noise is "
                    "blended too: with Noise Amplitude 0.4 (scale 1 m) the error grows to 1.2 % "
                    "(Half) and 5.8 % (Quarter) max, so Automatic at 1 % then bakes Full",
        items=(
            ('FULL', "Full", "Every pixel (the reference; slowest)"),
            ('HALF', "Half", "Every 2nd pixel. Measured at 1080p against Full (benchmarks/bench_rbf.py): "
                             "transmittance error 0.003 % mean, 0.05 % p99, 0.1 % max (airlight ~4x less); "
                             "~3.9x less CPU time with 3000 blobs, ~2.1x with a few broad ones"),
            ('QUARTER', "Quarter", "Every 4th pixel (default). Measured at 1080p against Full "
                                   "(benchmarks/bench_rbf.py): transmittance error 0.012 % mean, 0.2 % p99, "
                                   "0.53 % max (airlight ~4x less); ~6.9x less CPU time with 3000 blobs, "
                                   "~3.0x with a few broad ones. The error grows as the square of a pixel's "
                                   "size (x4 at 960x540, a 60-degree lens): Automatic then goes finer"),
        ),
        default='QUARTER',
    )
    homogeneous_resolution: EnumProperty(
        name="Airlight Resolution",
        description="Where the Sun 2005 bake (model Sun 2005 table, or Automatic choosing it) evaluates "
                    "the homogeneous fog's airlight: every pixel, or every 2nd / 4th pixel blended in "
                    "between where it is smooth. Depth edges, the surroundings of each light's image and "
                    "cells whose centre disagrees with the blend by more than 0.05 % stay exact per pixel; "
                    "the transmittance is always exact. Not with spot lights or fog objects",
        items=(
            ('FULL', "Full", "Every pixel (default; the reference)"),
            ('HALF', "Half", "Every 2nd pixel. Measured against Full at 1080p (five scenes): max 0.08 %, "
                             "mean below 0.002 %; about as costly as Full on 2 cores (the lattice's own work "
                             "eats the saving)"),
            ('QUARTER', "Quarter", "Every 4th pixel. Measured against Full at 1080p (five scenes): max 0.15 %, "
                                   "mean below 0.004 %; the airlight phase 1.4-2.3x cheaper with 3-4 lights"),
        ),
        default='FULL',
    )
    aa_samples: IntProperty(
        name="Edge Samples",
        description="Antialiasing at depth edges: pixels there are supersampled with "
                    "N x N samples so fog edges match the render's antialiased edges",
        default=4, min=1, max=8,
    )
    threads: IntProperty(
        name="Threads",
        description="Number of threads for the bake (0 uses all processor cores)",
        default=0, min=0, max=1024, soft_max=64,
    )
    cache_dir: StringProperty(
        name="Cache Folder",
        description="Folder where the baked fog passes are written as multilayer EXR "
                    "files, one per frame (fog_####.exr); // is relative to the .blend file",
        default="//airlight_cache/",
        subtype='DIR_PATH',
    )
    pass_precision: EnumProperty(
        name="Pass Precision",
        description="How the cache files store the fog passes. An animation keeps one file per "
                    "frame, so Half is the choice for long ones",
        items=(
            ('AUTO', "Automatic", "Half Float when the render's output has 8 bits per channel (PNG, "
                                  "JPEG, TIFF 8, movies), whose step its rounding stays below; Full Float "
                                  "for float (EXR, HDR) and 16-bit outputs"),
            ('FULL', "Full Float", "32-bit floats: the bake's values exactly (the street example "
                                   "at 960x540 with surface shading and light passes: 17.2 MB per frame)"),
            ('HALF', "Half Float", "16-bit floats, as Blender's own EXR output defaults to: relative "
                                   "rounding <= 0.05 % (absolute 3e-8 below 6e-5), files 4-13x smaller "
                                   "(the street example: 4.6 MB per frame), written ~4x faster"),
        ),
        default='AUTO',
    )
    light_passes: BoolProperty(
        name="Light Passes",
        description="Also write each fogged light's airlight as its own pass, "
                    "Fog.Airlight_<light name> (and Fog.Airlight_World with Environment Glow), "
                    "to grade each lamp's glow in the compositor; they sum to Fog.Airlight. "
                    "Written while the scene has at most Light Pass Limit fogged lights. Every "
                    "light but the costliest is baked once more on its own (one light: no extra "
                    "bake; each extra bake costs about its light's share of the frame's fog)",
        default=True,
    )
    light_pass_limit: IntProperty(
        name="Light Pass Limit",
        description="Light Passes are written only while the scene has at most this many "
                    "fogged lights (an area light or a collection's instances of a light count "
                    "once); above it the frame has the total Fog.Airlight alone and the console "
                    "says so",
        default=8, min=1, max=256,
    )
    lens_samples: IntProperty(
        name="Lens Samples",
        description="With the camera's Depth of Field on, the fog is baked this many times from "
                    "points spread over the lens aperture and averaged, so that out-of-focus "
                    "silhouettes blur in the fog passes as they do in the render (each sample "
                    "costs one bake). 1: one bake from the lens centre, sharp fog edges",
        default=8, min=1, max=64,
    )
    motion_samples: IntProperty(
        name="Motion Samples",
        description="With Motion Blur on, the fog is baked at this many instants spread over the "
                    "shutter and averaged, so that moving silhouettes blur in the fog passes as they "
                    "do in the render (each sample costs one bake; background renders and Bake Fog: "
                    "interactive renders cannot set the frame from their thread and bake the "
                    "frame's instant). 1: the frame's instant",
        default=4, min=1, max=32,
    )
    auto_composite: BoolProperty(
        name="Auto Composite",
        description="Keep the compositor fog nodes in sync: create them when needed and "
                    "point them at the baked passes of the frame being rendered",
        default=True,
    )
    rayleigh_density: FloatProperty(
        name="Rayleigh Density",
        description="Hoffman-Preetham model only: Rayleigh scattering coefficient of the air at "
                    "550 nm, per scene unit (clear air at sea level: about 1.2e-5 per metre). "
                    "It scatters and extinguishes blue more than red (1/wavelength^4); Density is "
                    "the Mie haze on top",
        default=1.2e-5, min=0.0, soft_max=0.01, max=100.0, step=1, precision=6,
    )
    volumetric_shadows: BoolProperty(
        name="Volumetric Shadows",
        description="Geometry blocks the light in the fog: light shafts through windows and "
                    "between buildings, no glow behind walls. Objects with Ray Visibility > Shadow "
                    "cast them, for lights with Cast Shadow on. Exact to the triangles; "
                    "Automatic leaves a light unshadowed where no caster is near enough to matter. "
                    "Off: unshadowed fog, as Sun et al. 2005 model it",
        default=True,
    )
    shadow_samples: IntProperty(
        name="Soft Shadow Samples",
        description="Volumetric shadows of point and spot lights with a Radius, and of suns with an "
                    "Angle, are cast from this many points of the light's sphere (directions over the "
                    "sun's disk), which soften the shafts' edges as Cycles does (1: from the light's "
                    "centre, hard edges). Each costs about one more shadowed bake. 0: Automatic, the "
                    "fewest (1, 8, 16, 32 or 64) whose effect, measured on small probe bakes of each "
                    "frame, is within the Accuracy target (1 % with an explicit model)",
        default=0, min=0, max=64, soft_max=32,
    )
    surface_shading: BoolProperty(
        name="Surface Shading",
        description="Cycles only: light surfaces through the fog (each fogged light's direct "
                    "light attenuated along its own path, plus the light the fog scatters onto "
                    "diffuse surfaces). Adds one light group per fogged light and the Diffuse "
                    "Color pass to the view layers automatically. Eevee and Workbench renders "
                    "keep the plain composite (render x Transmittance + Airlight)",
        default=True,
        update=_on_surface_changed,
    )
    surface_gloss: FloatProperty(
        name="Gloss Exponent",
        description="Cycles surface shading: Phong exponent of the fog's glossy glow (Sun 2005 "
                    "eq. 18, Gn), the point lights' scattered light seen in glossy reflections, "
                    "added per unit of the Glossy Color pass (enabled automatically). Higher is a "
                    "tighter lobe (about 2 / roughness^2 - 2 for a GGX roughness); 0 turns it off",
        default=0.0, min=0.0, max=10000.0, soft_max=200.0, step=100, precision=0,
        update=_on_surface_changed,
    )
    surface_glow_model: EnumProperty(
        name="Glow Model",
        description="Cycles surface shading: how the light the fog scatters onto diffuse surfaces "
                    "is computed",
        items=[
            ('EXACT', "Exact", "Hemisphere-clamped glow integral: Sun 2005 G0 for the isotropic "
                               "phase, its phase-aware generalisation (Biri 2006 eq. 8-13) otherwise; "
                               "table error <= 1 %"),
            ('BIRI06_EQ10', "Biri 2006 eq. 10", "The paper's own Lambert model (Gamma_L x cos, no "
                                                "hemisphere clamp): measured 15 % (isotropic) to 83 % "
                                                "(HG g = -0.9) low facing the light, no glow facing "
                                                "away. For comparison"),
        ],
        default='EXACT',
        update=_on_surface_changed,
    )
    environment_glow: BoolProperty(
        name="Environment Glow",
        description="Show the World through the fog (Sun 2005, eq. 25-27): bright parts of the "
                    "World's colour or Environment Texture glow, and the World is dimmed by the fog "
                    "up to the Environment Distance instead of hidden",
        default=False,
        update=_on_surface_changed,
    )
    environment_distance: FloatProperty(
        name="Environment Distance",
        description="Distance of the World's light sources (the sky, an HDRI's lamps and sun) from "
                    "the camera. The World is seen through density x distance of fog: larger "
                    "distances dim it more and widen its glows",
        default=50.0, min=1.0e-3, soft_min=1.0, soft_max=1000.0, max=1.0e7,
        subtype='DISTANCE', unit='LENGTH',
    )
    environment_sh_order: IntProperty(
        name="Glow Detail",
        description="Spherical-harmonic bands of the glow convolution: more bands give tighter "
                    "glows around small bright sources and cost more (time grows with the "
                    "square of the bands)",
        default=24, min=2, max=96, soft_max=64,
    )


class AirlightLightSettings(bpy.types.PropertyGroup):
    participate: BoolProperty(
        name="Scatter in Fog",
        description="Scatter this light in the fog",
        default=True,
    )


classes = (AirlightSceneSettings, AirlightLightSettings)


def register():
    for cls in classes:
        bpy.utils.register_class(cls)
    bpy.types.Scene.airlight = PointerProperty(type=AirlightSceneSettings)
    bpy.types.Light.airlight = PointerProperty(type=AirlightLightSettings)


def unregister():
    del bpy.types.Light.airlight
    del bpy.types.Scene.airlight
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
