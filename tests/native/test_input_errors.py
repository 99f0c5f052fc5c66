"""Invalid input raises ValueError with a message that names the problem."""
import os

import numpy as np
import pytest

import _native
from scene_util import perspective, plane_z


def args(**kw):
    v, t = plane_z(-3.0, x=(-5.0, 5.0), y=(-5.0, 5.0))
    a = dict(width=8, height=6, cam_to_world=np.eye(4), projection=perspective(1.0, 8, 6),
             vertices=v, triangles=t, light_positions=[[0.0, 1.0, -1.0]],
             light_intensities=[[1.0, 1.0, 1.0]], sigma_t=0.1)
    a.update(kw)
    return a


def test00_valid_args_bake():
    _native.bake(**args())


@pytest.mark.parametrize("kw, match", [
    (dict(width=0), "resolution"),
    (dict(height=-3), "resolution"),
    (dict(width=100000), "resolution"),
    (dict(sigma_t=-0.1), "sigma_t"),
    (dict(sigma_t=float("nan")), "sigma_t"),
    (dict(albedo=(1.0, -1.0, 1.0)), "albedo"),
    (dict(albedo=(1.0, 1.0)), "albedo"),
    (dict(cam_to_world=np.eye(3)), "cam_to_world"),
    (dict(cam_to_world=np.full((4, 4), np.nan)), "finite"),
    (dict(projection=np.zeros((4, 4))), "invertible"),
    (dict(vertices=np.zeros((4, 2), np.float32)), "vertices"),
    (dict(vertices=np.array([[0, 0, np.nan]] * 4, np.float32)), "vertices"),
    (dict(triangles=np.array([[0, 1, 7]], np.uint32)), "triangle index"),
    (dict(triangles=np.array([[0, 1, -1]])), "triangles"),
    (dict(triangles=np.array([[0.0, 1.0, 2.0]])), "integer"),
    (dict(light_positions=[[0.0, 1.0]]), "light_positions"),
    (dict(light_intensities=[[1.0, 1.0, 1.0]] * 2), "light_intensities"),
    (dict(light_intensities=[[1.0, -1.0, 1.0]]), "intensity"),
    (dict(light_positions=[[0.0, np.inf, 0.0]]), "position"),
    (dict(model="nope"), "sun05"),
    (dict(aa_samples=0), "aa_samples"),
    (dict(threads=-1), "threads"),
    (dict(progress=42), "progress"),
])
def test01_bake_rejects(kw, match):
    with pytest.raises(ValueError, match=match):
        _native.bake(**args(**kw))


def test02_write_exr_missing_directory(tmp_path):
    path = os.path.join(str(tmp_path), "no", "such", "dir", "fog.exr")
    with pytest.raises(RuntimeError):
        _native.write_exr(path, {"Airlight": np.zeros((4, 4, 3), np.float32)})


def test03_write_exr_bad_passes(tmp_path):
    path = str(tmp_path / "fog.exr")
    with pytest.raises(ValueError, match="shape"):
        _native.write_exr(path, {"Airlight": np.zeros((4, 4), np.float32)})
    with pytest.raises(ValueError, match="other passes"):
        _native.write_exr(path, {"A": np.zeros((4, 4, 3), np.float32), "B": np.zeros((4, 5, 3), np.float32)})
    with pytest.raises(ValueError):
        _native.write_exr(path, {})


def test04_write_exr_refuses_a_nul_in_the_path(tmp_path):
    """A NUL byte inside the path (or a channel name) is refused: the C string would end
    there, and the file (or channel) would get the truncated name without a word."""
    passes = {"Airlight": np.zeros((4, 4, 3), np.float32)}
    with pytest.raises(ValueError, match="path: contains a NUL byte"):
        _native.write_exr(str(tmp_path / "fog.exr\0.txt"), passes)
    assert os.listdir(tmp_path) == []
    with pytest.raises(ValueError, match="pass name: contains a NUL byte"):
        _native.write_exr(str(tmp_path / "fog.exr"), {"Air\0light": passes["Airlight"]})
    with pytest.raises(ValueError, match="layer_prefix: contains a NUL byte"):
        _native.write_exr(str(tmp_path / "fog.exr"), passes, layer_prefix="Fog\0.")
    assert os.listdir(tmp_path) == []


@pytest.mark.parametrize("kw, match", [
    (dict(vertices=plane_z(-3.0, x=(-5.0, 5.0), y=(-5.0, 5.0))[0].astype(np.complex64)), "vertices: .*complex"),
    (dict(light_positions=np.array([[0.0, 1.0, -1.0 + 1e-3j]])), "light_positions: .*complex"),
    (dict(albedo=(1.0, 1.0, 1.0j)), "albedo: .*complex"),
    (dict(cam_to_world=None), "cam_to_world: expected real numbers, got None"),
    (dict(light_intensities=[["1", "1", "1"]]), "light_intensities: .*dtype <U1"),
])
def test05_bake_refuses_values_that_are_not_real_numbers(kw, match):
    """Complex arrays (numpy would drop the imaginary part), None and strings are refused with
    a TypeError naming the argument, never cast."""
    with pytest.raises(TypeError, match=match):
        _native.bake(**args(**kw))


def test06_complex_e1_refuses_what_is_not_a_number():
    for z in (None, "1+2j", [1.0, None]):
        with pytest.raises(TypeError, match="z: expected real or complex numbers"):
            _native.complex_e1(z)
    assert _native.complex_e1(1.0) == pytest.approx(0.21938393439552027)  # real input still fine


@pytest.mark.parametrize("threads", [-1, 1025, 100000])
def test07_thread_counts_outside_0_to_1024_are_refused(threads):
    with pytest.raises(ValueError, match=r"threads must be in \[0, 1024\]"):
        _native.bake(**args(threads=threads))
    medium = _native.RbfMedium([[0.0, 0.0, 0.0]], [1.0], [1.0])
    with pytest.raises(ValueError, match=r"threads must be in \[0, 1024\]"):
        medium.optical_depth([[0.0, 0.0, -1.0]], [[0.0, 0.0, 1.0]], threads=threads)


def test08_threads_at_the_limit_bake():
    _native.bake(**args(threads=1024))


def test09_bake_larger_than_memory_is_refused_before_allocating():
    """32768 x 32768 with surface shading for 64 lights would take ~890 GB of images: refused
    with the estimate and the memory available, before any allocation (it used to run until
    the machine swapped or the process was killed)."""
    lights = dict(light_positions=[[0.0, 1.0, -1.0]] * 64, light_intensities=[[1.0, 1.0, 1.0]] * 64)
    assert 0.0 < _native.available_memory() < 890e9
    with pytest.raises(ValueError, match=r"the bake of 32768 x 32768 pixels needs about 889\.\d GB but only "
                                         r"[\d.]+ [GM]B of memory is available"):
        _native.bake(**args(width=32768, height=32768, surface=True, **lights))
