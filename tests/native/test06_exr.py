"""write_exr round trip through OpenImageIO's Python bindings."""
import numpy as np
import OpenImageIO as oiio
import pytest

import _native


def read(path):
    inp = oiio.ImageInput.open(path)
    assert inp, oiio.geterror()
    spec = inp.spec()
    pixels = inp.read_image(0, spec.nchannels, oiio.FLOAT)
    inp.close()
    return spec, pixels


@pytest.mark.parametrize("prefix", ["", "ViewLayer."])
def test01_round_trip(tmp_path, prefix):
    rng = np.random.default_rng(7)
    H, W = 5, 7
    passes = {"Airlight": rng.random((H, W, 3), dtype=np.float32) * 10,
              "Transmittance": rng.random((H, W, 3), dtype=np.float32)}
    path = str(tmp_path / "fog.exr")
    _native.write_exr(path, passes, layer_prefix=prefix)
    spec, pixels = read(path)
    assert (spec.width, spec.height) == (W, H)
    assert spec.format == oiio.FLOAT
    names = list(spec.channelnames)
    assert sorted(names) == sorted(f"{prefix}{p}.{c}" for p in passes for c in "RGB")
    for p, data in passes.items():
        for k, c in enumerate("RGB"):
            got = pixels[:, :, names.index(f"{prefix}{p}.{c}")]
            np.testing.assert_array_equal(got, data[:, :, k])  # float EXR: exact, top row first


def test02_bake_output_writes(tmp_path):
    out = {"Airlight": np.full((3, 4, 3), 0.25, np.float32)}
    path = str(tmp_path / "x.exr")
    _native.write_exr(path, out)
    _, pixels = read(path)
    assert np.all(pixels == 0.25)
