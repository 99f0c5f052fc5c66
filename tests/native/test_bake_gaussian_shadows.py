"""Volumetric shadows in Gaussian fog (fog objects): a black panel between a point light and
three Gaussians, against an independent reference.

The reference (numpy + scipy, no native code): the single-scattering integral along each
tested pixel's ray, sigma_s(x) / (4 pi |x - s|^2) exp(-T(s, x) - T(v, x)) V(x), with the
Gaussians' optical depths in closed form (erf) and the panel's visibility V written out
(the segment x -> s crossing the panel's rectangle), integrated by scipy.quad split where
V jumps (found by bisection). Checked:
  - model `quadrature` (visibility by shadow rays in its integrand) against it, 1e-4;
  - the Fogshop models (lit spans: each Gaussian's optical depth over them, eq. 11) against
    `quadrature`: on thin Gaussians, where Fogshop's own approximation holds, within its
    unshadowed error plus 0.5 %, and the light the shadow removes within 1 % of the total;
  - with the uniform fog alone (Gaussians of zero amplitude) Fogshop's lit spans are exact;
  - shadows on without casters, or every light's Cast Shadow off: bit-identical to off."""
import math

import numpy as np
import pytest
from scipy import integrate
from scipy.special import erf

import _native
from scene_util import camera_matrix, merge, perspective, pixel_dirs_camera, quad

W, H = 40, 28
FOV = math.radians(60.0)
SIGMA_T = 0.05
LIGHT = np.array([0.3, 0.4, -6.0])
I0 = 50.0
PANEL_Z, PANEL_X, PANEL_Y = -4.0, (-0.5, 1.1), (-0.4, 1.2)
BACK_Z = -14.0
CENTRES = np.array([[0.3, 0.4, -4.5], [0.0, 0.0, -3.0], [1.0, 0.5, -7.0]])
SCALES = np.array([0.8, 0.6, 0.5])
AMPLITUDES = np.array([0.3, 0.2, 0.4])


def geometry():
    back = quad([[-60, -60, BACK_Z], [60, -60, BACK_Z], [60, 60, BACK_Z], [-60, 60, BACK_Z]])
    panel = quad([[PANEL_X[0], PANEL_Y[0], PANEL_Z], [PANEL_X[1], PANEL_Y[0], PANEL_Z],
                  [PANEL_X[1], PANEL_Y[1], PANEL_Z], [PANEL_X[0], PANEL_Y[1], PANEL_Z]])
    return merge([back, panel]), panel


def bake(model, amplitudes=AMPLITUDES, shadows=True, **extra):
    (v, t), panel = geometry()
    args = dict(width=W, height=H, cam_to_world=camera_matrix(np.eye(3), np.zeros(3)),
                projection=perspective(FOV, W, H), vertices=v, triangles=t, light_positions=LIGHT[None],
                light_intensities=np.full((1, 3), I0), sigma_t=SIGMA_T, model=model, aa_samples=1, threads=2,
                shadows=shadows, rbf_centres=CENTRES, rbf_scales=SCALES, rbf_amplitudes=np.asarray(amplitudes),
                gaussian_resolution="full")
    args.update(extra)
    return _native.bake(**args)


# -- the independent reference ----------------------------------------------------------

def optical_depth(p, q, amplitudes):
    """T on the segment p -> q: sigma_t |q - p| + sum_i of the Gaussians' line integrals."""
    d = q - p
    L = np.linalg.norm(d)
    if L == 0.0:
        return 0.0
    u = d / L
    total = SIGMA_T * L
    for b, a, c in zip(CENTRES, SCALES, amplitudes):
        rel = b - p
        ts = rel @ u
        h2 = rel @ rel - ts * ts
        total += c * math.sqrt(math.pi) / (2 * a) * math.exp(-a * a * h2) * (erf(a * (L - ts)) - erf(-a * ts))
    return total


def extinction(x, amplitudes):
    return SIGMA_T + sum(c * math.exp(-a * a * ((x - b) @ (x - b))) for b, a, c in zip(CENTRES, SCALES, amplitudes))


def lit(x):
    """Whether x sees the light past the panel (z = PANEL_Z, x in PANEL_X, y in PANEL_Y)."""
    dz = LIGHT[2] - x[2]
    if dz == 0.0:
        return True
    u = (PANEL_Z - x[2]) / dz
    if not (0.0 < u < 1.0):
        return True
    c = x + u * (LIGHT - x)
    return not (PANEL_X[0] < c[0] < PANEL_X[1] and PANEL_Y[0] < c[1] < PANEL_Y[1])


def reference(d, depth, amplitudes):
    """I0 int_0^depth sigma(x) / (4 pi |x - s|^2) e^{-T(s, x) - T(0, x)} V(x) dt, x = t d."""
    def f(t):
        x = t * d
        if not lit(x):
            return 0.0
        r2 = (x - LIGHT) @ (x - LIGHT)
        return extinction(x, amplitudes) / (4 * math.pi * r2) * math.exp(
            -optical_depth(LIGHT, x, amplitudes) - optical_depth(np.zeros(3), x, amplitudes))
    ts = np.linspace(0.0, depth, 801)
    states = [lit(t * d) for t in ts]
    cuts = [0.0]
    for k in range(len(ts) - 1):
        if states[k] != states[k + 1]:
            lo, hi = ts[k], ts[k + 1]
            for _ in range(60):
                mid = 0.5 * (lo + hi)
                lo, hi = (mid, hi) if lit(mid * d) == states[k] else (lo, mid)
            cuts.append(0.5 * (lo + hi))
    a = LIGHT @ d  # the light's closest approach: a breakpoint for the 1/r^2 peak
    if 0.0 < a < depth:
        cuts.append(a)
    for b in CENTRES:
        if 0.0 < b @ d < depth:
            cuts.append(b @ d)
    cuts = sorted(cuts) + [depth]
    return I0 * sum(integrate.quad(f, lo, hi, epsabs=0.0, epsrel=1e-9, limit=400)[0]
                    for lo, hi in zip(cuts[:-1], cuts[1:]) if hi > lo)


def test_quadrature_against_the_independent_reference():
    result = bake("quadrature")
    A, depth = result["airlight"][..., 0].astype(np.float64), result["depth"]
    dirs = pixel_dirs_camera(FOV, W, H)
    # Pixels across the panel's shadow: a row through the light's image, and some around.
    rng = np.random.default_rng(5)
    picks = [(H // 2, i) for i in range(0, W, 3)] + [tuple(p) for p in rng.integers((0, 0), (H, W), size=(10, 2))]
    shadowed_somewhere = 0
    floor = 1e-5 * np.percentile(A, 99)  # a pixel in shadow but for a sliver: its float32 rounding
    for j, i in picks:
        d = dirs[j, i]
        ref = reference(d, float(depth[j, i]), AMPLITUDES)
        assert abs(A[j, i] - ref) <= 1e-4 * ref + floor, (j, i, A[j, i], ref)
        ts = np.linspace(0.0, float(depth[j, i]), 50)
        shadowed_somewhere += any(not lit(t * d) for t in ts)
    assert shadowed_somewhere >= 5   # the test crosses the shadow


def rel(a, b, floor):
    return np.abs(a - b) / np.maximum(b, floor)


def assert_fogshop_shadows_as_quadrature(**lights):
    """On thin Gaussians (Fogshop's approximation holds): Fogshop with shadows errs against
    QUADRATURE with shadows within its unshadowed error plus 0.5 %, and the shadow removes
    the same share of the light (within 1 % of the total)."""
    thin = AMPLITUDES * 0.05
    q_on, q_off, f_on, f_off = (bake(model, thin, shadows=on, **lights)["airlight"][..., 0].astype(np.float64)
                                for model in ("quadrature", "sun05") for on in (True, False))
    floor = 0.05 * np.percentile(q_on, 99)
    unshadowed_err = rel(f_off, q_off, floor).mean()
    shadowed_err = rel(f_on, q_on, floor).mean()
    assert shadowed_err < unshadowed_err + 0.005, (shadowed_err, unshadowed_err)
    removed_q, removed_f = 1 - q_on.sum() / q_off.sum(), 1 - f_on.sum() / f_off.sum()
    assert removed_q > 0.1, removed_q
    assert abs(removed_f - removed_q) < 0.01, (removed_f, removed_q)


def test_fogshop_lit_spans_against_quadrature_on_thin_gaussians():
    assert_fogshop_shadows_as_quadrature()


def test_fogshop_lit_spans_exact_for_the_uniform_fog():
    zero = np.zeros(3)
    q = bake("quadrature", zero)["airlight"][..., 0].astype(np.float64)
    f = bake("sun05", zero)["airlight"][..., 0].astype(np.float64)
    assert rel(f, q, 0.05 * np.percentile(q, 99)).max() < 1e-4


@pytest.mark.parametrize("model", ["sun05", "quadrature"])
def test_no_casters_or_no_cast_shadow_is_bit_identical(model):
    off = bake(model, shadows=False)["airlight"]
    empty = bake(model, occluder_vertices=np.zeros((0, 3), np.float32),
                 occluder_triangles=np.zeros((0, 3), np.uint32))["airlight"]
    np.testing.assert_array_equal(empty, off)
    np.testing.assert_array_equal(bake(model, light_shadows=[False])["airlight"], off)


def test_fogshop_spot_lit_spans_against_quadrature_on_thin_gaussians():
    """A spot (the point light's place, aimed past the panel at the camera) in Gaussian fog:
    the Fogshop models restrict its terms to its lit spans as the point light's."""
    spot = dict(light_positions=np.zeros((0, 3)), light_intensities=np.zeros((0, 3)),
                spot_positions=LIGHT[None], spot_axes=np.array([[0.0, 0.0, 1.0]]),
                spot_intensities=np.full((1, 3), I0), spot_size=np.array([math.radians(100.0)]),
                spot_blend=np.array([0.3]))
    assert_fogshop_shadows_as_quadrature(**spot)


def sun_lights(**extra):
    """A sun from the side (propagating along +x, a little away from the camera) and, casting
    alone (the camera sees through it), the half-plane z = -5, x <= 0.3: its shadow's edge
    runs diagonally through the far fog and the far Gaussian."""
    w = np.array([1.0, 0.2, -0.4])
    pv, pt = quad([[-60, -60, -5.0], [0.3, -60, -5.0], [0.3, 60, -5.0], [-60, 60, -5.0]])
    return dict(light_positions=np.zeros((0, 3)), light_intensities=np.zeros((0, 3)),
                sun_directions=(w / np.linalg.norm(w))[None], sun_irradiances=np.full((1, 3), 3.0),
                occluder_vertices=pv, occluder_triangles=pt, **extra)


@pytest.mark.parametrize("fog_top", [math.inf, 1.0])
def test_fogshop_sun_lit_spans_against_quadrature_on_thin_gaussians(fog_top):
    """A sun whose shadow crosses the Gaussians, with and without a fog layer's top
    (above the camera): the Fogshop models restrict its Gaussian terms and the uniform fog's
    to its lit spans as a point light's."""
    assert_fogshop_shadows_as_quadrature(**sun_lights(fog_top=fog_top))


def test_fogshop_sun_uniform_fog_lit_spans_exact():
    """The sun's uniform-fog term over the lit spans equals the quadrature's when the
    Gaussians are empty."""
    zero = np.zeros(3)
    q = bake("quadrature", zero, **sun_lights())["airlight"][..., 0].astype(np.float64)
    f = bake("sun05", zero, **sun_lights())["airlight"][..., 0].astype(np.float64)
    off = bake("sun05", zero, shadows=False, **sun_lights())["airlight"][..., 0].astype(np.float64)
    assert q.sum() < 0.9 * off.sum()
    assert rel(f, q, 0.05 * np.percentile(q, 99)).max() < 1e-4


def refined_errors(accuracy, label, **extra):
    """Fogshop's and the refined bake's relative errors against `quadrature` on thick Gaussians
    (12x the panel scene's), and the refined bake's stats."""
    thick = 12.0 * AMPLITUDES
    ref = bake("quadrature", thick, **extra)["airlight"][..., 0].astype(np.float64)
    fogshop = bake("sun05", thick, **extra)["airlight"][..., 0].astype(np.float64)
    r = bake("sun05", thick, gaussian_accuracy=accuracy, **extra)
    got = r["airlight"][..., 0].astype(np.float64)
    m = ref > 1e-6 * ref.max()
    e, e0 = np.abs(got - ref)[m] / ref[m], np.abs(fogshop - ref)[m] / ref[m]
    print(f"{label}, {accuracy:g}: Fogshop mean {e0.mean():.2e}; refined mean {e.mean():.2e} p99 "
          f"{np.percentile(e, 99):.2e}, {r['stats']['gaussian_marched_rays']} marches")
    return e, e0, r["stats"]


@pytest.mark.parametrize("accuracy", [0.05, 0.01])
def test_refined_shadowed_point_light_meets_the_accuracy(accuracy):
    """Automatic's refinement marches a shadowed point light's whole airlight over its lit spans
    (gaussian/march.h): on Gaussians thick enough that Fogshop's lit spans err by tens of
    percent, the refined bake is within the accuracy of `quadrature` (mean, p99 within 3x)."""
    e, e0, stats = refined_errors(accuracy, "shadowed point light")
    assert e0.mean() > 5 * accuracy  # (the case needs the refinement)
    assert stats["gaussian_marched_lights"] == 1
    assert e.mean() <= accuracy and np.percentile(e, 99) <= 3 * accuracy


@pytest.mark.parametrize("fog_top", [math.inf, 1.0])
@pytest.mark.parametrize("accuracy", [0.05, 0.01])
def test_refined_shadowed_sun_meets_the_accuracy(accuracy, fog_top):
    """The same for a sun whose shadow crosses thick Gaussians (its march takes the lit spans
    and its map the Gaussians' own shade), with and without a fog layer's top; `quadrature`
    integrates the sun's visibility itself."""
    e, e0, stats = refined_errors(accuracy, f"shadowed sun, top {fog_top}", **sun_lights(fog_top=fog_top))
    assert e0.mean() > 2 * accuracy  # (the case needs the refinement)
    assert stats["gaussian_marched_lights"] == 1
    assert e.mean() <= accuracy and np.percentile(e, 99) <= 3 * accuracy
