"""Independent references shared by the native tests, written out here in numpy and scipy
(never through _native): phase functions, the Gaussians' optical depth (Fogshop eq. 31),
the fog-layer paths of sunlight, Sun 2005's surface G by quadrature; and the relative
error statistics the bake tests hold the passes to."""
import math

import numpy as np
from scipy import integrate
from scipy.special import erf

INV4PI = 1.0 / (4.0 * math.pi)


# --- phase functions (mu: cosine between the light's travel direction and the scattered one)

def hg(mu, g):
    """Henyey-Greenstein with Cycles' sign: g > 0 scatters forward."""
    return INV4PI * (1 - g * g) / (1 + g * g - 2 * g * mu) ** 1.5


def phase_value(name, mu, g=0.0):
    """The named phase function at _mu_; the Mie names in either order, as _native takes them."""
    if name == "isotropic" or (name == "hg" and g == 0.0):
        return INV4PI
    if name == "hg":
        return hg(mu, g)
    if name == "rayleigh":
        return 3 * (1 + mu * mu) / (16 * math.pi)
    s = (1 + mu) / 2
    if name in ("hazy_mie", "mie_hazy"):
        return (1 + 9 * s ** 8) / (8 * math.pi)
    if name in ("murky_mie", "mie_murky"):
        return 33 * (1 + 50 * s ** 32) / (332 * math.pi)
    raise KeyError(name)


# --- Gaussian fog

def gaussian_depths(b, a, c, o, d, t0, t1):
    """Per Gaussian (centres _b_, scales _a_, amplitudes _c_) the optical depth
    int_t0^t1 c_i exp(-a_i^2 |o + t d - b_i|^2) dt along the unit direction _d_ (eq. 31 with
    scipy's erf, every Gaussian, no culling); _t1_ may be inf."""
    rel = b - o
    ts = rel @ d
    cr = np.cross(rel, d)
    h2 = np.sum(cr * cr, axis=1)
    return c * math.sqrt(math.pi) / (2 * a) * np.exp(-a * a * h2) * (erf(a * (t1 - ts)) - erf(a * (t0 - ts)))


# --- sun lamps in a fog layer

def sun_layer_paths(o, d, t0, t, fog_top, mu_s):
    """(view, sun): the lengths in fog of the view ray over [t0, t] and of the sunbeam from
    o + t d up to the fog's top, for fog below _fog_top_ (world z) and a sun whose light
    comes down at cosine _mu_s_ to the vertical; fog_top = inf: unbounded fog lit by an
    unattenuated sun (Hoffman & Preetham), sun = 0. None where o + t d lies above the top."""
    if not math.isfinite(fog_top):
        return t - t0, 0.0
    z = o[2] + t * d[2]
    if z > fog_top:
        return None
    if d[2] != 0.0:
        t_top = (fog_top - o[2]) / d[2]
        lo, hi = (t0, min(t, t_top)) if d[2] > 0 else (max(t0, t_top), t)
        view = max(0.0, hi - lo)
    else:
        view = t - t0
    return view, (fog_top - z) / mu_s


def layer_top_crossing(o, d, t0, t1, fog_top):
    """[t] where the view ray o + t d crosses the fog's top inside (t0, t1), else []: the
    break point a quadrature along the ray needs."""
    if math.isfinite(fog_top) and d[2] != 0.0:
        t_top = (fog_top - o[2]) / d[2]
        if t0 < t_top < t1:
            return [t_top]
    return []


# --- surface glow (Sun 2005 eq. 16)

def F(u, v):
    """Sun 2005's F(u, v) = int_0^v exp(-u tan xi) dxi by scipy."""
    return integrate.quad(lambda x: math.exp(-u * math.tan(x)), 0.0, v, epsabs=0, epsrel=1e-11, limit=200)[0]


def cosine_lobe_azimuth(gamma, theta, m=1.0):
    """int_0^2pi max(0, cos gamma cos theta + sin gamma sin theta cos phi)^m dphi: a clamped
    cosine lobe at angle _theta_ from the light, over the directions at angle _gamma_ from it."""
    a, b = math.cos(gamma) * math.cos(theta), math.sin(gamma) * math.sin(theta)
    return integrate.quad(lambda p: max(0.0, a + b * math.cos(p)) ** m, 0.0, 2 * math.pi, epsrel=1e-10,
                          points=[math.acos(-a / b)] if abs(b) > abs(a) else None, limit=200)[0]


def G_ref(T, theta, m=1.0):
    """Eq. 16 in coordinates about the light direction: int H(T, g) W_m(g, theta) dg."""
    def H(g):
        u = T * math.sin(g)
        return math.exp(-T * math.cos(g)) * (F(u, math.pi / 2) - F(u, g / 2))

    edge = abs(math.pi / 2 - theta)
    return integrate.quad(lambda g: H(g) * cosine_lobe_azimuth(g, theta, m), 0.0, math.pi,
                          points=[edge, math.pi - edge], epsrel=1e-9, limit=200)[0]


# --- error statistics

def rel_errors(x, ref, channel=0):
    """|x - ref| / ref per pixel in float64 where _ref_ exceeds 1e-6 of its 99.9th percentile
    (relative errors of the darkest pixels mean nothing); channel None: every channel."""
    if channel is not None:
        x, ref = x[..., channel], ref[..., channel]
    x = np.asarray(x, np.float64)
    y = np.asarray(ref, np.float64)
    m = y > 1e-6 * np.percentile(y, 99.9)
    return np.abs(x - y)[m] / y[m]
