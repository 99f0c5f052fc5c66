"""A light distribution over the whole sphere (spot_profiles: a point light's IES profile,
fitted as I(c) = I0 sum_k p_k c^k about an axis) against an independent scipy quadrature of
the single-scattering integral with that profile written out here, for the closed form
(Pegoraro 2010: sun05, pegoraro10), Biri's model and the quadrature reference; a spot light's
profile inside its cone (spot_profile_in_cone: Cycles' cos(theta) smoothstep times the IES);
the per-row choice of cone or profile; the argument checks."""
import math

import numpy as np
import pytest
from scipy import integrate, optimize

import _native
from reference_util import hg
from scene_util import floor_bake, per_pixel_to_floor, perspective, plane_z

W, H, FOV, SIGMA = 10, 8, 1.1, 0.2
LIGHT = np.array([0.4, 0.8, -4.0])
AXIS = np.array([0.2, -1.0, -0.3]) / np.linalg.norm([0.2, -1.0, -0.3])
PROFILE = [0.2, 0.5, 0.9]   # 0.2 + 0.5 c + 0.9 c^2 > 0 on [-1, 1]
PLANE_Z = -7.0


def spots(profile=PROFILE, size=math.pi, blend=0.0):
    return dict(spot_positions=[LIGHT], spot_axes=[AXIS], spot_intensities=[[1.0, 1.0, 1.0]], spot_size=[size],
                spot_blend=[blend], spot_profiles=[profile])


def bake(**kw):
    return floor_bake(_native.bake, W, H, FOV, PLANE_Z, **(dict(sigma_t=SIGMA) | kw))


def cone_factor(c, size, blend):
    """Cycles 3.4's spot factor cos(theta) smoothstep(...) (spot_attenuation), written out."""
    c0 = math.cos(0.5 * size)
    if c <= c0:
        return 0.0
    smooth = (1.0 - c0) * blend
    t = c - c0
    if smooth > 0.0 and t < smooth:
        u = t / smooth
        return c * u * u * (3.0 - 2.0 * u)
    return c


def edges(u, t1, cone):
    """Where the ray t u, t in (0, t1), crosses the spot's cone and its blend cone."""
    c0 = math.cos(0.5 * cone[0])
    ts = np.linspace(1e-9, t1, 4001)
    w = ts[:, None] * u - LIGHT
    c = (w @ AXIS) / np.linalg.norm(w, axis=1)
    out = []
    for level in sorted({c0, c0 + (1.0 - c0) * cone[1]}):
        for k in np.nonzero(np.diff(np.sign(c - level)))[0]:
            def f(t):
                x = t * u - LIGHT
                return float(x @ AXIS) / math.sqrt(x @ x) - level
            out.append(optimize.brentq(f, ts[k], ts[k + 1], xtol=1e-14))
    return out


def reference(g=0.0, profile=PROFILE, cone=None, extent=math.pi):
    """The airlight per pixel; _cone_ (size, blend): the profile inside that spot's cone;
    _extent_: the profile alone, dark beyond that polar angle."""
    def integral(u, t1):
        def f(t):
            w = t * u - LIGHT
            r = math.sqrt(w @ w)
            c = float(AXIS @ w) / r
            I = max(0.0, sum(p * c ** k for k, p in enumerate(profile)))
            if cone is not None:
                I *= cone_factor(c, *cone)
            if c <= math.cos(extent):
                I = 0.0
            return I * hg(-(w @ u) / r, g) * math.exp(-SIGMA * (r + t)) / (r * r)

        tc = float(LIGHT @ u)
        pts = [tc] if 0.0 < tc < t1 else []
        if cone is not None:   # the cone's and the blend's edges: kinks of the integrand
            pts += edges(u, t1, cone)
        if extent < math.pi:   # the extent's step
            pts += edges(u, t1, (2.0 * extent, 0.0))
        pts = sorted(pts) or None
        return SIGMA * integrate.quad(f, 0.0, t1, points=pts, epsabs=1e-14, epsrel=1e-10, limit=800)[0]

    return per_pixel_to_floor(FOV, W, H, PLANE_Z, integral)


@pytest.fixture(scope="module")
def ref_iso():
    return reference()


@pytest.mark.parametrize("model, rtol", [("sun05", 1e-6), ("sun05_exact", 1e-6), ("pegoraro10", 1e-6),
                                         ("biri06", 1e-6), ("quadrature", 1e-6)])
def test01_profile_matches_quadrature(model, rtol, ref_iso):
    np.testing.assert_allclose(bake(model=model, **spots()), ref_iso, rtol=rtol)


@pytest.mark.parametrize("model", ["pegoraro10", "quadrature", "biri06"])
def test02_anisotropic_phase(model):
    np.testing.assert_allclose(bake(model=model, phase="hg", g=0.5, **spots()), reference(g=0.5), rtol=1e-5)


def test03_constant_profile_is_a_point_light():
    point = bake(light_positions=[LIGHT], light_intensities=[[1.0] * 3], model="sun05_exact")
    np.testing.assert_allclose(bake(model="sun05_exact", **spots(profile=[1.0])), point, rtol=1e-6)


def test04_zero_row_keeps_the_cone_and_rows_are_per_spot():
    two = dict(spot_positions=[LIGHT, LIGHT + 1.0], spot_axes=[AXIS, AXIS], spot_intensities=[[1.0] * 3] * 2,
               spot_size=[math.pi, 0.8], spot_blend=[0.0, 0.2], spot_profiles=[PROFILE, [0.0, 0.0, 0.0]])
    cone_only = dict(spot_positions=[LIGHT + 1.0], spot_axes=[AXIS], spot_intensities=[[1.0] * 3], spot_size=[0.8],
                     spot_blend=[0.2])
    got = bake(model="sun05_exact", **two)
    np.testing.assert_allclose(got, bake(model="sun05_exact", **spots()) + bake(model="sun05_exact", **cone_only),
                               rtol=1e-6)


def test05_shadows_and_surfaces_take_the_profile(ref_iso):
    v, t = plane_z(PLANE_Z, x=(-80.0, 80.0), y=(-80.0, 80.0))
    lit = bake(model="sun05_exact", shadows=True, **spots())   # the floor casts no shadow on the fog above it
    np.testing.assert_allclose(lit, ref_iso, rtol=1e-5)
    out = _native.bake(width=W, height=H, cam_to_world=np.eye(4), projection=perspective(FOV, W, H), vertices=v,
                       triangles=t, light_positions=np.zeros((0, 3)), light_intensities=np.zeros((0, 3)),
                       sigma_t=SIGMA, aa_samples=1, surface=True, **spots())
    assert all(np.all(np.isfinite(a)) for a in out.values() if isinstance(a, np.ndarray))


@pytest.mark.parametrize("kw, match", [
    (dict(spot_profiles=[[0.1, float("nan")]]), "profile coefficients must be finite"),
    (dict(spot_size=[1.0]), "a profile .* needs spot_size pi, spot_blend 0"),
    (dict(spot_profiles=[[1.0], [1.0]]), r"spot_profiles: expected shape \(1, K \+ 1\)"),
    (dict(spot_profiles=[[1.0] * 18]), "at most 17 coefficients"),
    (dict(spot_profile_in_cone=[True, False]), "spot_profile_in_cone: expected one flag per light"),
    (dict(spot_profile_in_cone=[True], spot_spread=[0.5]), "cannot go with a spread"),
    (dict(spot_profile_extent=[0.0]), r"profile_extent must be in \(0, pi\]"),
    (dict(spot_profile_extent=[4.0]), r"profile_extent must be in \(0, pi\]"),
    (dict(spot_profile_extent=[1.0], spot_profile_in_cone=[True], spot_size=[1.0]), "needs a profile over the sphere"),
])
def test06_bad_profiles_are_refused(kw, match):
    args = spots()
    args.update(kw)
    with pytest.raises(ValueError, match=match):
        bake(**args)


def test07_profiles_need_spots_and_homogeneous_fog():
    with pytest.raises(ValueError, match="spot_profiles needs the spot lights"):
        bake(spot_profiles=[[1.0]])
    with pytest.raises(ValueError, match="IES profile .* not in Gaussian fog"):
        bake(rbf_centres=[[0.0, 0.0, -5.0]], rbf_scales=[1.0], rbf_amplitudes=[0.5], **spots())


CONE = (1.3, 0.3)   # the spot's size (rad) and blend for its IES inside the cone


def in_cone(profile=PROFILE):
    return spots(profile, *CONE) | dict(spot_profile_in_cone=[True])


@pytest.fixture(scope="module")
def ref_cone():
    return reference(cone=CONE)


@pytest.mark.parametrize("model, rtol", [("sun05", 1e-6), ("sun05_exact", 1e-6), ("pegoraro10", 1e-6),
                                         ("biri06", 1e-6), ("quadrature", 1e-6)])
def test08_spot_profile_inside_its_cone(model, rtol, ref_cone):
    got = bake(model=model, **in_cone())
    assert (ref_cone > 0.0).mean() > 0.2   # the cone crosses a good part of the view
    np.testing.assert_allclose(got, ref_cone, rtol=rtol, atol=1e-12 * ref_cone.max())


@pytest.mark.parametrize("model", ["pegoraro10", "quadrature"])
def test09_spot_profile_inside_its_cone_anisotropic(model):
    ref = reference(g=0.5, cone=CONE)
    np.testing.assert_allclose(bake(model=model, phase="hg", g=0.5, **in_cone()), ref, rtol=1e-5,
                               atol=1e-12 * ref.max())


def test10_constant_profile_in_a_cone_is_the_spot():
    plain = spots(*([None] * 0)) | dict(spot_size=[CONE[0]], spot_blend=[CONE[1]])
    plain.pop("spot_profiles")
    np.testing.assert_allclose(bake(model="sun05_exact", **in_cone([2.5])), 2.5 * bake(model="sun05_exact", **plain),
                               rtol=1e-6)


def degree16():
    """A forward-peaked profile of degree 16 (positive: the truncated generating function of
    the Legendre polynomials at 0.8, sum 0.8^n P_n(c))."""
    from numpy.polynomial import legendre
    return list(legendre.leg2poly([0.8 ** n for n in range(17)]))


@pytest.mark.parametrize("model", ["sun05", "pegoraro10", "biri06"])
def test11_degree_16_profiles(model):
    """IES fits go to degree 16 (addon/airlight/ies.py): alone, and times a spot's blend (degree 20)."""
    p = degree16()
    np.testing.assert_allclose(bake(model=model, **spots(p)), reference(profile=p), rtol=1e-6)
    ref = reference(profile=p, cone=CONE)
    np.testing.assert_allclose(bake(model=model, **in_cone(p)), ref, rtol=1e-6, atol=1e-12 * ref.max())


@pytest.mark.parametrize("model", ["sun05", "pegoraro10", "biri06", "quadrature"])
def test12_a_profile_dark_beyond_its_extent(model):
    """A point light's IES dark past its last lit angle (a downlight): cut there, not fitted."""
    extent = 1.1
    ref = reference(extent=extent)
    got = bake(model=model, **spots(), spot_profile_extent=[extent])
    assert 0.2 < (ref > 0.0).mean() < 0.9   # the cut crosses the view
    np.testing.assert_allclose(got, ref, rtol=1e-6, atol=1e-12 * ref.max())
    # pi: the whole sphere, as without it.
    np.testing.assert_allclose(bake(model=model, **spots(), spot_profile_extent=[math.pi]), bake(model=model, **spots()),
                               rtol=1e-12)
