"""Determinism: a frame baked with different `threads`, or in another process, gives the
same passes bit for bit (a render farm's workers, docs/architecture.md "Determinism").

Every pass of the bake over a scene that takes each path that splits work between threads:
row bands and their edge pixels (depth-edge supersampling with clustering), the homogeneous
lattice, the Gaussian splat (tiles, the reduced lattice, noise), spot and sun lamps, surface
shading, volumetric shadows, and the table, Pegoraro and quadrature models. The bound across
machines whose CPUs pick different SIMD clones is stated in docs/architecture.md, not tested
here (one CPU)."""
import os
import subprocess
import sys

import numpy as np
import pytest

import _native
from scene_util import camera_matrix, gaussian_cloud, merge, perspective, plane_y, rotation_x

W, H = 120, 80
THREADS = (1, 2)


def _box(x0, x1, y0, y1, z0, z1):
    v = np.array([(x, y, z) for x in (x0, x1) for y in (y0, y1) for z in (z0, z1)], np.float32)
    faces = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    t = np.array([(a, b, c) for a, b, c, d in faces] + [(a, c, d) for a, b, c, d in faces], np.uint32)
    return v, t


def _scene(**kw):
    floor = plane_y(-3.0, x=(-300.0, 300.0), z=(1.0, -200.0))
    v, t = merge([floor, _box(-1, 1, -3, 0.5, -9, -7), _box(2, 3, -3, 2, -15, -12)])
    a = dict(width=W, height=H, cam_to_world=camera_matrix(rotation_x(0.05), np.zeros(3)),
             projection=perspective(1.0, W, H), vertices=v, triangles=t,
             light_positions=[[4.0, 3.0, -8.0], [-5.0, 2.0, -14.0]],
             light_intensities=[[50.0, 40.0, 30.0], [20.0, 20.0, 30.0]], sigma_t=0.05, clip_start=0.1, aa_samples=4)
    a.update(kw)
    return a


_c, _s, _a = gaussian_cloud(60, seed=3)
_SPOTS = dict(spot_positions=[[0.0, 4.0, -10.0]], spot_axes=[[0.0, -1.0, 0.0]], spot_intensities=[[80.0] * 3],
              spot_size=[1.0], spot_blend=[0.2])
_SUNS = dict(sun_directions=[[0.3, -1.0, -0.2]], sun_irradiances=[[1.0, 1.0, 1.0]], fog_top=2.0)
_GAUSS = dict(rbf_centres=_c * 4 + [0.0, -1.0, -10.0], rbf_scales=_s / 4, rbf_amplitudes=_a)
VARIANTS = {
    "sun05_lattice": dict(homogeneous_resolution="quarter"),
    "sun05_spots_suns_surface": dict(surface=True, surface_phong_exponent=20.0, **_SPOTS, **_SUNS),
    "gaussians_quarter": dict(gaussian_resolution="quarter", **_GAUSS),
    "gaussians_noise": dict(noise_amplitude=0.3, **_GAUSS),
    "biri06_hg_surface": dict(model="biri06", phase="hg", g=0.6, surface=True),
    "shadows": dict(shadows=True, **_SPOTS),
    "pegoraro10": dict(model="pegoraro10", phase="hg", g=0.3),
    "quadrature": dict(model="quadrature", **_SPOTS),
}


def passes(variant, threads):
    result = _native.bake(**_scene(threads=threads, **VARIANTS[variant]))
    return {k: np.asarray(v) for k, v in result.items() if k != "stats"}


def dump(path):
    """Child process: every variant's passes with threads=2, into one .npz."""
    np.savez(path, **{f"{v}/{k}": p for v in VARIANTS for k, p in passes(v, 2).items()})


def _assert_same_bits(a, b, what):
    assert a.keys() == b.keys(), what
    for k in a:
        assert a[k].dtype == b[k].dtype and a[k].shape == b[k].shape, (what, k)
        assert a[k].tobytes() == b[k].tobytes(), f"{what}: pass {k} differs"


@pytest.mark.parametrize("variant", list(VARIANTS))
def test01_threads_give_the_same_bits(variant):
    reference = passes(variant, THREADS[0])
    assert np.isfinite(reference["airlight"]).all() and reference["airlight"].max() > 0.0
    for threads in THREADS[1:] + (THREADS[0],):
        _assert_same_bits(reference, passes(variant, threads), f"{variant}, threads={threads}")


def test02_another_process_gives_the_same_bits(tmp_path):
    path = tmp_path / "child.npz"
    here = os.path.dirname(os.path.abspath(__file__))
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([here, os.path.dirname(_native.__file__)]))
    code = f"import test_bake_determinism as t; t.dump({str(path)!r})"
    subprocess.run([sys.executable, "-c", code], env=env, check=True, timeout=600, cwd=here)
    child = np.load(path)
    for variant in VARIANTS:
        mine = passes(variant, 2)
        theirs = {k: child[f"{variant}/{k}"] for k in mine}
        _assert_same_bits(mine, theirs, f"{variant}, other process")
