"""A point or spot light at the eye (docs/conventions.md, "A light at the eye").

With the fog starting at the eye (clip_start = 0, perspective camera) the single scattering
along every ray, sigma_s p(pi) I0 int_0 e^{-2 sigma_t x} / x^2 dx, diverges like 1/x at the
eye: every pixel is infinite, and the bake used to return ~1e12 per unit intensity on every
pixel without a word. It is refused, naming the light. With the fog starting at the near
plane (Blender's cameras: Clip Start > 0) the integral is finite, and the bake matches it."""
import math

import numpy as np
import pytest
from scipy import integrate

import _native
from scene_util import perspective, pixel_dirs_camera, plane_z

W, H, FOV, SIGMA = 8, 6, 1.0, 0.1
PLANE_Z = -3.0


def bake(**kw):
    v, t = plane_z(PLANE_Z, x=(-50.0, 50.0), y=(-50.0, 50.0))
    a = dict(width=W, height=H, cam_to_world=np.eye(4), projection=perspective(FOV, W, H), vertices=v,
             triangles=t, light_positions=[[3.0, 3.0, 3.0], [0.0, 0.0, 0.0]],
             light_intensities=[[1.0, 1.0, 1.0]] * 2, sigma_t=SIGMA, aa_samples=1)
    a.update(kw)
    return _native.bake(**a)


@pytest.mark.parametrize("where", [(0.0, 0.0, 0.0), (0.0, 0.0, 1e-7), (-3e-7, 2e-7, 0.0)])
def test01_light_at_the_eye_with_fog_from_the_eye_is_refused(where):
    with pytest.raises(ValueError, match=r"light 1 is at the camera .* the fog starts at the eye "
                                         r"\(clip_start = 0\).* set clip_start > 0"):
        bake(light_positions=[[3.0, 3.0, 3.0], list(where)])


def test02_spot_light_at_the_eye_is_refused():
    spots = dict(spot_positions=[[0.0, 0.0, 0.0]], spot_axes=[[0.0, 0.0, -1.0]], spot_intensities=[[1.0] * 3],
                 spot_size=[1.0], spot_blend=[0.1])
    with pytest.raises(ValueError, match="spot light 0 is at the camera"):
        bake(light_positions=[[3.0, 3.0, 3.0]], light_intensities=[[1.0] * 3], **spots)


def test03_light_near_the_eye_or_without_fog_still_bakes():
    near = bake(light_positions=[[3.0, 3.0, 3.0], [0.0, 0.0, 1e-5]])["airlight"]
    assert np.all(np.isfinite(near)) and near.min() > 0.0
    assert bake(sigma_t=0.0)["airlight"].max() == 0.0


@pytest.mark.parametrize("model, rtol", [("sun05", 2e-3), ("sun05_exact", 1e-6), ("quadrature", 1e-6)])
def test04_light_at_the_eye_with_fog_from_the_near_plane_is_the_finite_integral(model, rtol):
    """clip_start = c: along a ray of unit direction d (cos_view = -d_z), the fog runs from
    t0 = c / cos_view to the floor at t1 = 3 / cos_view, attenuated from the near point:
    La = sigma I0 / (4 pi) int_t0^t1 e^{-sigma (x - t0)} e^{-sigma x} / x^2 dx (isotropic)."""
    clip = 0.1
    out = bake(light_positions=[[0.0, 0.0, 0.0]], light_intensities=[[1.0] * 3], clip_start=clip,
               model=model)["airlight"][..., 0]
    d = pixel_dirs_camera(FOV, W, H)
    cos_view = -d[..., 2]
    expected = np.empty((H, W))
    for j in range(H):
        for i in range(W):
            t0, t1 = clip / cos_view[j, i], -PLANE_Z / cos_view[j, i]
            f = lambda x: math.exp(-SIGMA * (x - t0) - SIGMA * x) / (x * x)  # noqa: E731
            expected[j, i] = SIGMA / (4.0 * math.pi) * integrate.quad(f, t0, t1, epsrel=1e-12)[0]
    np.testing.assert_allclose(out, expected, rtol=rtol)
