"""Volumetric shadows with the camera's crossings rasterized on the film
(shadow/screen_crossings.h, the default) against the same bake with every ray traced through
Embree (shadow_crossings='traced') and against the `quadrature` model, whose integrand asks a
shadow ray at each node (visibility found without the shadow volumes).

The scenes put casters where the film path leaves their caps out or must keep them: casters
that are the camera's geometry (the rays end on them), one cut by the near clip, one past the
far clip that the rays pass through and whose shadow they cross, casters the camera does not
see (Ray Visibility > Camera off), and edge pixels supersampled. Heavy casters (more faces
than the film's pixels pay for) are traced: the bake is the traced one bit for bit."""
import math

import numpy as np
import pytest

import _native
from scene_util import camera_matrix, merge, perspective, quad

W, H = 48, 32
FOV = math.radians(70.0)
SIGMA_T = 0.08


def box(lo, hi):
    """A closed axis-aligned box (12 triangles)."""
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    faces = [
        [[x0, y0, z0], [x0, y1, z0], [x1, y1, z0], [x1, y0, z0]],
        [[x0, y0, z1], [x1, y0, z1], [x1, y1, z1], [x0, y1, z1]],
        [[x0, y0, z0], [x1, y0, z0], [x1, y0, z1], [x0, y0, z1]],
        [[x0, y1, z0], [x0, y1, z1], [x1, y1, z1], [x1, y1, z0]],
        [[x0, y0, z0], [x0, y0, z1], [x0, y1, z1], [x0, y1, z0]],
        [[x1, y0, z0], [x1, y1, z0], [x1, y1, z1], [x1, y0, z1]],
    ]
    return merge([quad(f) for f in faces])


def street(seed=3):
    rng = np.random.default_rng(seed)
    parts = [quad([[-60, -60, 0], [60, -60, 0], [60, 60, 0], [-60, 60, 0]])]
    for _ in range(14):
        lo = np.array([rng.uniform(-12, 12), rng.uniform(2, 30), 0.0])
        parts.append(box(lo, lo + [rng.uniform(0.3, 3), rng.uniform(0.3, 3), rng.uniform(0.5, 7)]))
    parts.append(box([-0.6, 0.2, 1.2], [0.6, 0.45, 2.2]))  # just ahead of the eye: the near clip cuts it
    return parts


def camera():
    # At (0, 0, 1.6) looking along +y, a little down.
    a = math.radians(84.0)
    R = np.array([[1, 0, 0], [0, math.cos(a), -math.sin(a)], [0, math.sin(a), math.cos(a)]])
    return camera_matrix(R, np.array([0.0, 0.0, 1.6]))


LIGHTS = np.array([[2.0, 8.0, 5.0], [-5.0, 18.0, 3.5], [4.0, 26.0, 6.0]])
INTENSITIES = np.array([[300.0] * 3, [200.0] * 3, [400.0] * 3])


def bake(parts, model="sun05", crossings="film", clip=(0.5, 1000.0), occluders=None, **extra):
    v, t = merge(parts)
    args = dict(width=W, height=H, cam_to_world=camera(), projection=perspective(FOV, W, H, *clip), vertices=v,
                triangles=t, light_positions=LIGHTS, light_intensities=INTENSITIES, sigma_t=SIGMA_T, model=model,
                threads=2, shadows=True, shadow_crossings=crossings, clip_start=clip[0], clip_end=clip[1])
    if occluders is not None:
        args.update(occluder_vertices=occluders[0].astype(np.float32), occluder_triangles=occluders[1].astype(np.uint32))
    args.update(extra)
    return _native.bake(**args)["airlight"][..., 0].astype(np.float64)


def relative(got, ref):
    scale = np.percentile(ref, 99)
    assert scale > 0.0
    return np.abs(got - ref) / np.maximum(ref, 0.05 * scale)


def check(parts, **kw):
    film = bake(parts, **kw)
    traced = bake(parts, crossings="traced", **kw)
    unshadowed = bake(parts, **dict(kw, shadows=False))
    assert np.isfinite(film).all()
    d = relative(film, traced)
    assert d.mean() < 1e-5 and np.percentile(d, 99) < 1e-4, (d.mean(), np.percentile(d, 99), d.max())
    # The shadows are there (the test can tell a lost cap or face).
    assert relative(unshadowed, traced).mean() > 0.02
    return film


def test_casters_that_the_camera_sees():
    check(street())


def test_supersampled_edges():
    check(street(), aa_samples=4)


def test_caster_past_the_far_clip_still_shadows():
    # A wall at y = 40 past the far clip (30 m): the rays pass through it, into its shadow.
    wall = quad([[-30, 40, 0], [30, 40, 0], [30, 40, 12], [-30, 40, 12]])
    lights = np.array([[0.0, 55.0, 6.0]])
    kw = dict(clip=(0.5, 30.0), light_positions=lights, light_intensities=np.array([[3000.0] * 3]))
    parts = [wall, quad([[-60, -60, -0.01], [60, -60, -0.01], [60, 10, -0.01], [-60, 10, -0.01]])]
    film = check(parts, **kw)
    # Without the wall the light reaches the rays past it: the wall's shadow is in the film bake.
    assert film.sum() < 0.9 * bake(parts[1:], **kw).sum()


def test_casters_the_camera_does_not_see():
    parts = street()
    ov, ot = merge(parts[1:])
    check(parts[:1], occluders=(ov, ot))


def test_casters_some_of_which_the_camera_sees():
    """The casters the camera sees lead the occluders (occluder_seen_triangles: their caps cut
    no ray but within the near clip), shadow-only ones follow (theirs count everywhere): film
    and traced agree, and the bake is the one that keeps every cap."""
    parts = street()
    hidden = box([-3.0, 6.0, 0.0], [-1.0, 7.0, 3.0])  # casts shadows only
    ov, ot = merge(parts + [hidden])
    seen = len(merge(parts)[1])
    kept = check(parts, occluders=(ov, ot))
    cut = check(parts, occluders=(ov, ot), occluder_seen_triangles=seen)
    d = relative(cut, kept)
    assert d.mean() < 1e-5 and np.percentile(d, 99) < 1e-4, (d.mean(), np.percentile(d, 99))
    # Counting the shadow-only box among the seen ones loses its caps: its shadow goes wrong.
    wrong = bake(parts, occluders=(ov, ot), occluder_seen_triangles=len(ot), crossings="traced")
    assert relative(wrong, kept).max() > 0.05
    with pytest.raises(ValueError, match="occluder_seen_triangles"):
        bake(parts, occluders=(ov, ot), occluder_seen_triangles=len(ot) + 1)


def test_surface_glow_takes_the_camera_rays_cut():
    """The glow's half-lines end at their first hit with the camera's geometry, so they cross
    none of the seen casters' caps and take the camera rays' cut (glow_shadow.h): the glow is
    the one that keeps every cap. The shadow-only box's caps count for them too: counting it
    among the seen ones changes the glow its shadow falls in."""
    parts = street()
    hidden = box([-3.0, 6.0, 0.0], [-1.0, 7.0, 3.0])
    ov, ot = merge(parts + [hidden])
    seen = len(merge(parts)[1])

    def glow(**kw):
        v, t = merge(parts)
        out = _native.bake(width=W, height=H, cam_to_world=camera(), projection=perspective(FOV, W, H, 0.5, 1000.0),
                           vertices=v, triangles=t, light_positions=LIGHTS, light_intensities=INTENSITIES,
                           sigma_t=SIGMA_T, model="sun05", threads=2, clip_start=0.5, clip_end=1000.0, surface=True,
                           occluder_vertices=ov.astype(np.float32), occluder_triangles=ot.astype(np.uint32), **kw)
        return out["surface_glow"][..., 0].astype(np.float64)

    kept = glow(shadows=True)
    cut = glow(shadows=True, occluder_seen_triangles=seen)
    d = relative(cut, kept)
    assert d.mean() < 1e-6 and d.max() < 1e-4, (d.mean(), d.max())
    assert relative(glow(shadows=False), kept).mean() > 0.02  # (the glow is shadowed)
    wrong = glow(shadows=True, occluder_seen_triangles=len(ot))
    assert relative(wrong, kept).max() > 0.005


def test_film_against_the_shadow_ray_quadrature():
    parts = street()
    got = bake(parts)
    ref = bake(parts, model="quadrature", crossings="traced")
    d = relative(got, ref)
    assert d.mean() < 2e-3 and np.percentile(d, 99) < 1e-2, (d.mean(), np.percentile(d, 99))


def test_bad_crossings_argument():
    with pytest.raises(ValueError, match="shadow_crossings"):
        bake(street()[:1], crossings="rasterized")


def test_heavy_casters_are_traced():
    """A shadow-only caster (Ray Visibility > Camera off: the rays pass it, so its caps count)
    of thousands of small triangles at 48 x 32 pixels: far more faces than
    ScreenCrossings::kMaxFacesPerPixel allows, so the default bake traces them, bit for bit the
    traced bake, and still shadows the fog. The same caster seen by the camera (its caps left
    out) keeps the film."""
    n = 60  # 7200 triangles over the first light
    cells = [quad([[x, y, 4.0], [x + 0.1, y, 4.0], [x + 0.1, y + 0.1, 4.0], [x, y + 0.1, 4.0]])
             for x in np.arange(n) * 0.1 - 1.0 for y in np.arange(n) * 0.1 + 5.0]
    occluders = merge(street() + cells)
    film, traced = bake(street(), occluders=occluders), bake(street(), occluders=occluders, crossings="traced")
    np.testing.assert_array_equal(film, traced)
    assert np.sum(film) < 0.98 * np.sum(bake(street()))
    seen = bake(street() + cells)
    assert not np.array_equal(seen, bake(street() + cells, crossings="traced"))  # (the film's own rounding)
