"""Demo: render the open .blend headless with Airlight fog -> <outdir>/.

Run as `tools/blender.sh -b blend_examples/street.blend --python tools/demo.py -- out`
(this is what `make demo` does). The render_pre handler bakes the fog of the frame into
<outdir>/fog_####.exr (multilayer: Fog.Airlight, Fog.Transmittance) and the compositor
applies `render * Transmittance + Airlight`; the composite is saved as <outdir>/<name>.png.
"""

import os
import sys
import time

import bpy

argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
outdir = os.path.abspath(argv[0] if argv else "out")
os.makedirs(outdir, exist_ok=True)

scene = bpy.context.scene
if not hasattr(scene, "airlight"):
    print("demo: the Airlight add-on is not enabled (run through tools/blender.sh)", file=sys.stderr)
    sys.exit(1)

name = os.path.splitext(os.path.basename(bpy.data.filepath))[0] or "untitled"
scene.airlight.enabled = True
scene.airlight.cache_dir = outdir + os.sep
scene.render.filepath = os.path.join(outdir, name + ".png")
scene.render.image_settings.file_format = "PNG"

t0 = time.perf_counter()
bpy.ops.render.render(write_still=True)
elapsed = time.perf_counter() - t0

png = scene.render.filepath
exr = os.path.join(outdir, f"fog_{scene.frame_current:04d}.exr")
ok = os.path.isfile(png) and os.path.isfile(exr)
print(f"demo: render + fog in {elapsed:.1f} s; image {png}; fog passes {exr}")
sys.exit(0 if ok else 1)
