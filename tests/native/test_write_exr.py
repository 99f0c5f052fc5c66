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


def test03_half_precision(tmp_path):
    """half=True stores 16-bit floats: each value is numpy's float16 rounding of the input
    (round to nearest even, as OpenEXR's half), relative error <= 2^-11 from 6.1e-5 up;
    smooth passes (a bake's) compress to a fraction of the float file."""
    rng = np.random.default_rng(3)
    H, W = 48, 64
    y, x = np.mgrid[0:H, 0:W]
    smooth = (np.exp(-((x - 30.0) ** 2 + (y - 20.0) ** 2) / 300.0)[..., None] * [3.0, 2.0, 1.0]).astype(np.float32)
    passes = {"Airlight": smooth, "Transmittance": rng.random((H, W, 3), dtype=np.float32),
              "Tiny": (rng.random((H, W, 3)) * 1e-6).astype(np.float32)}
    half_path, float_path = str(tmp_path / "half.exr"), str(tmp_path / "float.exr")
    _native.write_exr(half_path, passes, half=True)
    _native.write_exr(float_path, passes)
    spec, pixels = read(half_path)
    assert spec.format == oiio.HALF
    names = list(spec.channelnames)
    for name, a in passes.items():
        got = np.stack([pixels[..., names.index(f"{name}.{c}")] for c in "RGB"], axis=-1)
        np.testing.assert_array_equal(got, a.astype(np.float16).astype(np.float32))
        big = np.abs(a) >= 6.1e-5
        assert (np.abs(got - a)[big] <= 2.0 ** -11 * np.abs(a)[big]).all()
        assert (np.abs(got - a)[~big] <= 3e-8).all()
    smooth_only = {"Airlight": smooth}
    _native.write_exr(half_path, smooth_only, half=True)
    _native.write_exr(float_path, smooth_only)
    import os
    assert os.path.getsize(half_path) < 0.5 * os.path.getsize(float_path)


@pytest.mark.parametrize("compression", ["auto", "none", "rle", "zips", "zip", "piz"])
def test04_lossless_compressions_round_trip_exactly(tmp_path, compression):
    """Every lossless compression gives the float passes back bit for bit, and names itself
    in the file (auto: PIZ for floats)."""
    rng = np.random.default_rng(11)
    passes = {"Airlight": (rng.random((37, 53, 3), dtype=np.float32) * 1e3).astype(np.float32),
              "Transmittance": rng.random((37, 53, 3), dtype=np.float32)}
    path = str(tmp_path / f"fog_{compression}.exr")
    _native.write_exr(path, passes, compression=compression)
    spec, pixels = read(path)
    assert spec.getattribute("compression") == ("piz" if compression == "auto" else compression)
    names = list(spec.channelnames)
    for p, data in passes.items():
        for k, c in enumerate("RGB"):
            np.testing.assert_array_equal(pixels[:, :, names.index(f"{p}.{c}")], data[:, :, k])


def test05_half_auto_is_zip_and_unknown_compression_refused(tmp_path):
    passes = {"Airlight": np.full((4, 4, 3), 0.5, np.float32)}
    path = str(tmp_path / "h.exr")
    _native.write_exr(path, passes, half=True)
    spec, _ = read(path)
    assert spec.getattribute("compression") == "zip" and spec.format == oiio.HALF
    with pytest.raises(ValueError, match="unknown compression 'lzma'"):
        _native.write_exr(str(tmp_path / "bad.exr"), passes, compression="lzma")


@pytest.mark.parametrize("half,compression", [(False, "none"), (False, "piz"), (True, "auto"), (True, "piz")])
def test06_images_taller_than_a_strip_keep_every_row_in_place(tmp_path, half, compression):
    """write_exr interleaves and writes the rows in strips (256 rows): every row of an image
    of several strips and a partial last one lands where it belongs, in float exactly and in
    half to its rounding."""
    rng = np.random.default_rng(11)
    H, W = 600, 9
    rows = np.arange(H, dtype=np.float32)[:, None, None]
    passes = {"Airlight": rows + rng.random((H, W, 3), dtype=np.float32),
              "Transmittance": rng.random((H, W, 3), dtype=np.float32)}
    path = str(tmp_path / "tall.exr")
    _native.write_exr(path, passes, half=half, compression=compression)
    spec, pixels = read(path)
    names = list(spec.channelnames)
    for p, data in passes.items():
        for k, c in enumerate("RGB"):
            got = pixels[:, :, names.index(f"{p}.{c}")]
            if half:
                np.testing.assert_allclose(got, data[:, :, k], rtol=2.0 ** -11, atol=3e-8)
            else:
                np.testing.assert_array_equal(got, data[:, :, k])
