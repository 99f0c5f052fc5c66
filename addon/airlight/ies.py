"""IES light profiles (IESNA LM-63, photometric type C) as the fog takes them.

Cycles multiplies a light's emission by its IES Texture's value in the direction from the
light (cycles/src/util/ies.cpp, kernel/svm/ies.h): candela x candela multiplier x ballast
factor x ballast-lamp factor x 4 pi / 177.83, at the polar angle from the lamp's -Z (0
straight down the lamp's axis) and the azimuth about it; beyond the file's last polar angle
it is 0; on a spot light the value multiplies the spot's cone. The fog takes the profile's
average about the axis, fitted over the sphere with
Legendre polynomials in c = cos(polar angle) (Pegoraro et al. 2010's light distributions: the
bake integrates the polynomial in closed form), the lowest degree whose mean error over the
sphere is below the accuracy asked, at most MAX_DEGREE; the fit's error is reported, and the
azimuthal variation is dropped (the fog around a lamp averages it; its surface light is
Cycles' own). Nothing here reads Blender data or calls the native module.
"""

import hashlib
import math
from typing import NamedTuple

import numpy as np
from numpy.polynomial import legendre

CANDELA_TO_WATT = 4.0 * math.pi / 177.83   # Cycles' factor (D65's luminous efficacy)
MAX_DEGREE = 16
_SAMPLES = 4001   # uniform in c: uniform over the sphere for a profile about an axis
OUTSIDE_WEIGHT = 0.01   # a spot's fit: the least-squares weight outside its cone (fit())


class IESError(ValueError):
    """An IES file the fog cannot read (the message says what is wrong)."""


class Profile(NamedTuple):
    """The axially averaged profile (polar angles in degrees, values in Cycles' units)."""
    polar: np.ndarray
    values: np.ndarray


class Fit(NamedTuple):
    coefficients: np.ndarray   # I(c) = sum_k coefficients[k] c^k (monomials, for the bake)
    degree: int
    mean_error: float          # mean |fit - I| over the sphere / mean I (spots: weighted by the cone)
    max_error: float           # max |fit - I| / max I (spots: of the light inside the cone)
    mean: float                # the profile's mean over the sphere (spots: weighted by the cone)
    extent: float = math.pi    # points: the polar angle (rad) beyond which the profile is dark


def _numbers(text):
    """The numbers after the TILT line, as Cycles' parser reads them (commas as blanks)."""
    text = text.replace(",", " ").replace("\r", "")
    at = text.find("\nTILT=")
    if at < 0:
        raise IESError("no TILT= line (not an IES LM-63 file)")
    rest = text[at + 1:]
    line, _, body = rest.partition("\n")
    tokens = body.split()
    if line.strip().startswith("TILT=INCLUDE"):
        # Lamp-to-luminaire geometry, the number of tilt angles, then angles and factors.
        try:
            count = int(float(tokens[1]))
        except (IndexError, ValueError):
            raise IESError("its TILT=INCLUDE block is truncated") from None
        tokens = tokens[2 + 2 * count:]
    try:
        return [float(t) for t in tokens]
    except ValueError as ex:
        raise IESError(f"a value is not a number ({ex})") from None


def parse(text):
    """(polar degrees (V,), azimuth degrees (A,), values (A, V)) of an IES file's text, in
    Cycles' units. IESError for what Cycles would not load or the fog does not take."""
    values = _numbers(text)
    if len(values) < 13:
        raise IESError("its photometric header is truncated")
    multiplier, n_polar, n_azimuth, kind = values[2], int(values[3]), int(values[4]), int(values[5])
    ballast, ballast_lamp = values[10], values[11]
    if kind != 1:
        raise IESError(f"photometric type {'A' if kind == 3 else 'B' if kind == 2 else kind} is not in the fog "
                       "(type C only)")
    if n_polar < 2 or n_azimuth < 1:
        raise IESError(f"it has {n_polar} polar and {n_azimuth} azimuth angles")
    body = values[13:]
    need = n_polar + n_azimuth + n_polar * n_azimuth
    if len(body) < need:
        raise IESError(f"it holds {len(body)} of the {need} angles and values its header announces")
    polar = np.array(body[:n_polar])
    azimuth = np.array(body[n_polar:n_polar + n_azimuth])
    candela = np.array(body[n_polar + n_azimuth:need]).reshape(n_azimuth, n_polar)
    if not (np.all(np.isfinite(candela)) and np.all(np.diff(polar) > 0) and np.all(np.diff(azimuth) >= 0)):
        raise IESError("its angles are not increasing or its values not finite")
    if polar[0] < -1e-4 or polar[-1] > 180.0 + 1e-4:
        raise IESError(f"its polar angles run from {polar[0]:g} to {polar[-1]:g} degrees (type C: 0 to 180)")
    factor = multiplier * ballast * ballast_lamp * CANDELA_TO_WATT
    return polar, azimuth, factor * candela


def axial(polar, azimuth, values):
    """The profile averaged over the azimuth (the trapezoid over the file's range: Cycles
    mirrors a quadrant or half to the full circle, which keeps that mean)."""
    if len(azimuth) == 1 or azimuth[-1] - azimuth[0] <= 0.0:
        return Profile(polar, np.maximum(values[0], 0.0))
    weights = np.zeros(len(azimuth))
    steps = np.diff(azimuth)
    weights[:-1] += 0.5 * steps
    weights[1:] += 0.5 * steps
    return Profile(polar, np.maximum(weights @ values / weights.sum(), 0.0))


def sample(profile, c):
    """The profile at the cosines _c_ (linear in the polar angle; 0 beyond its last angle)."""
    theta = np.degrees(np.arccos(np.clip(c, -1.0, 1.0)))
    out = np.interp(theta, profile.polar, profile.values)
    return np.where((theta > profile.polar[-1] + 1e-9) | (theta < profile.polar[0] - 1e-9), 0.0, out)


def cone_factor(c, spot_size, spot_blend):
    """Cycles 3.4's spot factor at the cosines _c_ from the spot's axis (spot_attenuation):
    cos(theta) times the smoothstep over the blend, 0 outside the cone."""
    c = np.asarray(c, dtype=np.float64)
    c0 = math.cos(0.5 * spot_size)
    smooth = (1.0 - c0) * spot_blend
    u = np.clip((c - c0) / smooth, 0.0, 1.0) if smooth > 0.0 else np.ones_like(c)
    return np.where(c > c0, c * u * u * (3.0 - 2.0 * u), 0.0)


def lit_extent(profile):
    """The polar angle (degrees) beyond which _profile_ is dark: the angle after its last
    positive value (where the linear interpolation reaches 0), or its last angle (Cycles
    gives 0 beyond it); 180: lit to the end."""
    positive = np.nonzero(profile.values > 0.0)[0]
    if not len(positive):
        return 0.0
    return float(profile.polar[min(positive[-1] + 1, len(profile.polar) - 1)])


def fit(profile, accuracy, cone=None):
    """The lowest-degree Legendre fit (at most MAX_DEGREE) whose mean error over the sphere is
    at most _accuracy_ (a fraction), as a Fit.

    A point light's profile dark beyond lit_extent (a downlight) is fitted over the lit
    directions only, as a spot's over its cone below; the bake cuts the light at that extent
    (spot_profile_extent), so the fit leaves no residual glow in the dark ones.

    _cone_ (spot_size, spot_blend): a spot light's profile, which Cycles multiplies into the
    spot's cone_factor. The errors are then weighted by that factor (the light the fog gets).
    Outside the cone, which hides it, the fit follows the profile's value at the cone's edge
    with the least-squares weight OUTSIDE_WEIGHT: the fit spends its degree on the cone, and
    the polynomial stays bounded over the whole circle, whose Fourier series the closed form
    integrates (measured: at most 1.3x the cone's peak, and degree 16 -> 6-7 for a batwing
    in 70-100 deg cones)."""
    c = np.linspace(-1.0, 1.0, _SAMPLES)
    target = sample(profile, c)
    weight = np.ones_like(c)
    fit_weight = None
    extent = math.pi
    c0 = None
    if cone is not None:
        weight = cone_factor(c, *cone)
        c0 = math.cos(0.5 * cone[0])
    elif lit_extent(profile) < 180.0 - 1e-6:
        extent = math.radians(lit_extent(profile))
        c0 = math.cos(extent)
        weight = (c > c0).astype(np.float64)
    if c0 is not None:
        target = np.where(c > c0, target, sample(profile, np.array([c0]))[0])
        fit_weight = np.where(c > c0, 1.0, OUTSIDE_WEIGHT)
    mean = float((target * weight).mean())
    peak = float((target * weight).max())
    if not peak > 0.0:
        raise IESError("its intensities are all zero" + (" inside the spot's cone" if cone is not None else ""))
    best = None
    for degree in range(0, MAX_DEGREE + 1):
        coef = legendre.legfit(c, target, degree, w=fit_weight)
        miss = np.abs(legendre.legval(c, coef) - target) * weight
        mean_error = float(miss.mean() / mean)
        best = Fit(legendre.leg2poly(coef), degree, mean_error, float(miss.max() / peak),
                   mean / float(weight.mean()) if cone is not None else mean, extent)
        if mean_error <= accuracy:
            break
    return best


_CACHE = {}


def fit_text(text, accuracy, cone=None):
    """fit(axial(*parse(text)), accuracy, cone), kept per text, accuracy and cone (a file is
    fitted once)."""
    key = (hashlib.sha1(text.encode("utf-8", "replace")).hexdigest(), float(accuracy),
           None if cone is None else tuple(float(v) for v in cone))
    if key not in _CACHE:
        if len(_CACHE) > 64:
            _CACHE.clear()
        _CACHE[key] = fit(axial(*parse(text)), accuracy, cone)
    return _CACHE[key]


def fit_light(text, accuracy, light):
    """(Fit, None) of _light_'s profile _text_ (fit_text with the light's light_cone), or
    (None, why it cannot be read): such a light bakes without its profile."""
    try:
        return fit_text(text, accuracy, light_cone(light)), None
    except IESError as ex:
        return None, str(ex)


def light_cone(light):
    """fit's _cone_ for a Blender light (bpy or scene_description.LightInstance): a spot's
    (spot_size, spot_blend), None for a point light."""
    return (float(light.spot_size), float(light.spot_blend)) if light.type == 'SPOT' else None


def describe(result):
    """One line for the panel and the console: a Fit's degree and errors."""
    return (f"IES profile fitted to degree {result.degree}: {100.0 * result.mean_error:.2g} % mean error over the "
            f"light, {100.0 * result.max_error:.2g} % of the peak at most; its variation about the axis is "
            "averaged out")
