"""EXR files read in the tests through OpenImageIO, independently of Blender (the Blender
tests import these through conftest.py; the GPU tests put this folder on sys.path)."""

import numpy as np


def read_exr(path):
    """(H, W, C) float32 pixels and channel names."""
    import OpenImageIO as oiio
    inp = oiio.ImageInput.open(path)
    assert inp is not None, oiio.geterror()
    spec = inp.spec()
    pixels = np.asarray(inp.read_image(oiio.FLOAT)).reshape(spec.height, spec.width, spec.nchannels)
    names = list(spec.channelnames)
    inp.close()
    return pixels, names


def exr_pass(path, name):
    """The (H, W, 3) RGB of pass _name_ of the fog layer ("Fog.<name>.R" ...)."""
    pixels, names = read_exr(path)
    index = [names.index(f"Fog.{name}.{c}") for c in "RGB"]
    return pixels[..., index]
