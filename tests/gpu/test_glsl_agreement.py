"""GLSL vs C++ agreement: shaders/sun05_airlight.glsl, fed the very F table the C++ uses
(`_native.special_F_table`, uploaded as a texture), must reproduce
`_native.sun05_airlight(..., model="sun05")` and `_native.special_F(exact=False)`.

This is the test that keeps the preview's GLSL and the bake's C++ from drifting. Inputs
are rounded to float32 first and the C++ reference is evaluated on those rounded values,
so the differences measured are those of the float32 GLSL evaluation (and of the GPU's
texture filtering), not of the inputs.

Tolerances: float32 has a relative epsilon of 6e-8; the Sun 2005 formula loses a few
digits in exp/atan/tan and in the difference F(A1, v1) - F(A1, v0) where both terms are
close, and GPU bilinear filtering may use reduced-precision weights. We require
p99 < 1e-3 and max < 1e-2 relative, over values above an absolute floor of 1e-6 times
the largest reference (below it the fog is invisible next to the rest of the image).
"""

import math

import gpu
import numpy as np
import pytest

from conftest import draw_fullscreen

N = 64  # N x N input points per quantity

P99_TOL = 1e-3
MAX_TOL = 1e-2


def _airlight_inputs(rng):
    """(N, N, 4) float32: sigma_t, Dsv, cos_gamma, Dvp; covers thin to thick fog, lights
    near and far, grazing and head-on directions, surfaces before/behind the light, sky."""
    n = N * N
    sigma_t = 10.0 ** rng.uniform(-3.0, 0.5, n)
    Dsv = 10.0 ** rng.uniform(-1.0, 2.0, n)
    cos_gamma = rng.uniform(-1.0, 1.0, n)
    # a share of near-singular directions (gamma -> 0 and -> pi)
    k = n // 8
    cos_gamma[:k] = np.sign(rng.uniform(-1, 1, k)) * (1.0 - 10.0 ** rng.uniform(-6, -2, k))
    Dvp = 10.0 ** rng.uniform(-1.5, 2.5, n)
    Dvp[rng.uniform(0, 1, n) < 0.1] = np.inf  # rays that hit nothing
    q = np.stack([sigma_t, Dsv, cos_gamma, Dvp], axis=-1).astype(np.float32)
    # Rays exactly through the light diverge (inf); keep the random set away from them.
    return q.reshape(N, N, 4)


def _f_inputs(rng):
    """(N, N, 4) float32: u, T = tan v, 0, 0 with u over and beyond the table range and v
    over [0, pi/2] including both ends."""
    n = N * N
    u = np.concatenate([rng.uniform(0.0, 2.0, n // 4), 10.0 ** rng.uniform(-4, 1.5, n - n // 4)])
    v = rng.uniform(0.0, math.pi / 2, n)
    v[:16] = 0.0
    v[16:32] = math.pi / 2
    u[-16:] = 0.0  # F(0, v) = v
    T = np.tan(v)
    T[16:32] = np.inf
    f = np.zeros((n, 4), np.float32)
    f[:, 0] = u
    f[:, 1] = T
    return f.reshape(N, N, 4)


def _rel_stats(gpu_values, reference, floor_fraction=1e-6):
    ref = np.asarray(reference, np.float64).ravel()
    got = np.asarray(gpu_values, np.float64).ravel()
    finite = np.isfinite(ref)
    floor = floor_fraction * np.max(np.abs(ref[finite]))
    use = finite & (np.abs(ref) > floor)
    rel = np.abs(got[use] - ref[use]) / np.abs(ref[use])
    worst = np.flatnonzero(use)[np.argmax(rel)] if rel.size else -1
    return dict(count=int(use.sum()), max=float(rel.max()), p99=float(np.percentile(rel, 99)),
                mean=float(rel.mean()), worst_index=int(worst),
                nonfinite_gpu=int((~np.isfinite(got[use])).sum()))


@pytest.fixture(scope="module")
def evaluated(gs, native):
    try:
        gs.shader_path("sun05_airlight.glsl")
    except FileNotFoundError as ex:
        pytest.fail(f"{ex}: the shared GLSL kernel is missing")
    rng = np.random.default_rng(2005)
    a_in = _airlight_inputs(rng)
    f_in = _f_inputs(rng)
    ftex, table = gs.f_table_texture(native)
    shader = gs.create_fullscreen_shader(
        "agreement", "test_airlight_frag.glsl", libs=("sun05_airlight.glsl",),
        samplers=("Ftab", "airlight_inputs", "f_inputs"))
    off = gpu.types.GPUOffScreen(N, N, format='RGBA32F')
    try:
        draw_fullscreen(off, shader, gs.fullscreen_batch(shader),
                        samplers=(("Ftab", ftex), ("airlight_inputs", gs.float_texture(a_in)),
                                  ("f_inputs", gs.float_texture(f_in))))
        out = gs.read_offscreen(off)
    finally:
        off.free()
    return dict(a_in=a_in.astype(np.float64), f_in=f_in.astype(np.float64), out=out, table=table)


def test01_sun05_airlight_matches_cpp(native, evaluated):
    q = evaluated["a_in"]
    ref = native.sun05_airlight(q[..., 0], q[..., 1], q[..., 2], q[..., 3], model="sun05")
    got = evaluated["out"][..., 0]
    s = _rel_stats(got, ref)
    w = np.unravel_index(s["worst_index"], ref.shape)
    print(f"\nsun05_airlight GLSL vs C++ (sun05, {s['count']} points): "
          f"max {s['max']:.3g}, p99 {s['p99']:.3g}, mean {s['mean']:.3g}; worst at "
          f"(sigma_t, Dsv, cos_gamma, Dvp) = {tuple(q[w])}: GLSL {got[w]:.7g} C++ {ref[w]:.7g}")
    assert s["nonfinite_gpu"] == 0
    assert s["p99"] < P99_TOL
    assert s["max"] < MAX_TOL


def test02_sun05_airlight_vs_exact_F(native, evaluated):
    """Report only: the GLSL against the exact-F model (the table's own error)."""
    q = evaluated["a_in"]
    ref = native.sun05_airlight(q[..., 0], q[..., 1], q[..., 2], q[..., 3], model="sun05_exact")
    s = _rel_stats(evaluated["out"][..., 0], ref)
    print(f"\nsun05_airlight GLSL vs C++ sun05_exact: max {s['max']:.3g}, p99 {s['p99']:.3g}, "
          f"mean {s['mean']:.3g}")
    assert s["mean"] < 0.05  # loose: the table's documented accuracy is the physics tests' job


def test03_airlight_F_matches_cpp_table(native, evaluated):
    f = evaluated["f_in"]
    u, T = f[..., 0], f[..., 1]
    v = np.arctan(T)  # arctan(inf) = pi/2
    ref = native.special_F(u, v, exact=False)
    got = evaluated["out"][..., 1]
    s = _rel_stats(got, ref)
    w = np.unravel_index(s["worst_index"], ref.shape)
    print(f"\nairlight_F GLSL vs C++ table ({s['count']} points): max {s['max']:.3g}, "
          f"p99 {s['p99']:.3g}, mean {s['mean']:.3g}; worst at (u, T) = ({u[w]:.7g}, {T[w]:.7g}): "
          f"GLSL {got[w]:.7g} C++ {ref[w]:.7g}")
    exact = native.special_F(u, v, exact=True)
    e = _rel_stats(got, exact)
    print(f"airlight_F GLSL vs exact F: max {e['max']:.3g}, p99 {e['p99']:.3g}, mean {e['mean']:.3g}")
    assert s["nonfinite_gpu"] == 0
    assert s["p99"] < P99_TOL
    assert s["max"] < MAX_TOL


def test04_limits_without_cpp(evaluated):
    """Independent of the C++: F(u, 0) = 0 and F(0, v) = v hold in the GLSL."""
    f = evaluated["f_in"]
    got = evaluated["out"][..., 1]
    at_v0 = f[..., 1] == 0.0
    assert at_v0.any() and np.all(np.abs(got[at_v0]) < 1e-6)
    u0 = f[..., 0] == 0.0
    v = np.arctan(f[..., 1])
    assert u0.any()
    np.testing.assert_allclose(got[u0], v[u0], rtol=1e-3, atol=1e-6)
