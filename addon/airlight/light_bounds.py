"""Cheap rigorous bounds of one light's airlight over a camera's frame, for the Automatic
model's light skipping (model_choice.light_plan). Plain numpy, no bpy.

Homogeneous fog of extinction sigma, albedo omega, phase p with p_min <= p <= p_max.
A view ray from v (direction d, fog from t0 on) past a point light s of intensity I0:
    La = omega sigma I0 int_t0^t1 p e^{-sigma (d(x) + t - t0)} / d(x)^2 dt,   d(x) = |x - s|.
Upper bound, any ray: d(x)^2 >= h^2 + (t - a)^2 (h: distance from s to the ray's line) and
d(x) + t - t0 >= |s - x0| (triangle inequality, x0 = the ray's start), so
    La <= omega sigma p_max I0 e^{-sigma D_min} int dt / (h^2 + (t - a)^2)
       <= omega sigma p_max I0 pi e^{-sigma D_min} / h,
with D_min the least distance from the light to a ray start, and also (d(x) >= h, so
e^{-sigma (d + t - t0)} <= e^{-sigma h} e^{-sigma (t - t0)})
    La <= omega p_max I0 e^{-sigma h} / h^2;
the smaller of the two is used. When the light lies behind every ray (angle >= 90 deg to
all of them) d(x)^2 >= D^2 + t^2 along each ray from the eye and the first bound halves
(int_0^inf dt / (D^2 + t^2) = pi / (2 D)). Over the frame h >= h_min,
the distance from s to the nearest camera ray: 0 if the light is in the frame (never
skipped), else D sin(alpha) with alpha the angle from the light's direction to the
frustum (D if alpha >= 90 deg) for perspective cameras; the distance from the light to
the frame rectangle across the view axis for orthographic ones. Spot lights: the same
(Cycles' profile I0 cos(theta) smoothstep(...) <= I0). Sun lamps (irradiance E):
La <= omega p_max E int sigma e^{-sigma t} dt <= omega p_max E (their light is at most E
inside the fog).

Lower bound, for every ray whose first surface lies at least one mean free path 1/sigma
beyond its start (the pixels where fog is the picture): over t in [t0, t0 + 1/sigma],
d(x) <= |s - x0| + t - t0 <= D_max + 1/sigma and the attenuation exponent is at most
sigma D_max + 2, so
    La >= omega p_min I0 e^{-2} e^{-sigma D_max} / (D_max + 1/sigma)^2,
D_max the largest distance from the light to a ray start. Sun without a fog top:
La >= omega p_min E (1 - 1/e). Spots and suns under a fog top: 0 (they may light none of
those rays).

Skipping a set of lights changes every pixel's airlight by at most the sum of their upper
bounds; light_plan skips the faintest lights while that sum stays below the accuracy
target times the sum of all lights' lower bounds, so every pixel's error is below the
target times the fog brightness of the least-lit pixel that looks at least one mean free
path deep (on such pixels: a relative error below the target).
"""

import math

import numpy as np

E2 = math.exp(-2.0)


def phase_range(phase, g):
    """(p_min, p_max) in 1/sr of the native phase name ("isotropic", "hg", "rayleigh",
    "mie_hazy", "mie_murky") with HG's g (phase.h's forms)."""
    four_pi = 4.0 * math.pi
    if phase == "isotropic" or (phase == "hg" and g == 0.0):
        return 1.0 / four_pi, 1.0 / four_pi
    if phase == "hg":
        a = abs(g)
        return (1.0 - a) / (four_pi * (1.0 + a) ** 2), (1.0 + a) / (four_pi * (1.0 - a) ** 2)
    if phase == "rayleigh":
        return 3.0 / (16.0 * math.pi), 6.0 / (16.0 * math.pi)
    if phase == "mie_hazy":
        return 1.0 / (8.0 * math.pi), 10.0 / (8.0 * math.pi)
    if phase == "mie_murky":
        return 33.0 / (332.0 * math.pi), 33.0 * 51.0 / (332.0 * math.pi)
    raise ValueError(f"unknown phase '{phase}'")


class Frame:
    """A camera's frame: cam_to_world (4, 4), the 4 corners of its view frame in camera
    space (Blender's camera.view_frame(scene), in order around the frame), whether it is
    orthographic, and the near clip distance along the view axis. Its methods take (N, 3)
    arrays of world points (all lights at once: the panel redraws this)."""

    def __init__(self, cam_to_world, corners, ortho, clip_start=0.0):
        self.m = np.asarray(cam_to_world, dtype=np.float64)
        self.rot = self.m[:3, :3]
        self.eye = self.m[:3, 3]
        c = np.asarray(corners, dtype=np.float64).reshape(4, 3)
        self.ortho = bool(ortho)
        self.clip_start = float(clip_start)
        if self.ortho:
            self.xmin, self.xmax = c[:, 0].min(), c[:, 0].max()
            self.ymin, self.ymax = c[:, 1].min(), c[:, 1].max()
            self.near_corners = np.column_stack([c[:, 0], c[:, 1], np.full(4, -self.clip_start)])
            return
        dirs = c / -c[:, 2:3]                      # scaled to unit view-axis depth
        self.dirs = dirs / np.linalg.norm(dirs, axis=1, keepdims=True)
        self.near_corners = dirs * self.clip_start
        centre = self.dirs.sum(axis=0)
        normals, wedge_a, wedge_b = [], [], []
        for i in range(4):
            a, b = self.dirs[i], self.dirs[(i + 1) % 4]
            n = np.cross(a, b)
            n /= np.linalg.norm(n)
            normals.append(n if n @ centre >= 0.0 else -n)   # pointing into the frustum
            # p lies in the wedge between a and b iff (a x p).(a x b) >= 0 and
            # (p x b).(a x b) >= 0, i.e. p.((a x b) x a) >= 0 and p.(b x (a x b)) >= 0.
            ab = np.cross(a, b)
            wedge_a.append(np.cross(ab, a))
            wedge_b.append(np.cross(b, ab))
        self.normals = np.array(normals)
        self.wedge_a, self.wedge_b = np.array(wedge_a), np.array(wedge_b)

    def local(self, points):
        """World points (N, 3) -> camera space."""
        return (np.asarray(points, dtype=np.float64).reshape(-1, 3) - self.eye) @ self.rot

    def ray_distances(self, points):
        """(h, behind), each (N,): the least distance from each world point to a camera
        ray's line (0 inside the frame), and whether the point is at least 90 deg from every
        ray (then h is its distance to the eye and the bound's half-line form applies)."""
        q = self.local(points)
        if self.ortho:
            dx = np.maximum(np.maximum(self.xmin - q[:, 0], 0.0), q[:, 0] - self.xmax)
            dy = np.maximum(np.maximum(self.ymin - q[:, 1], 0.0), q[:, 1] - self.ymax)
            return np.hypot(dx, dy), np.zeros(len(q), dtype=bool)
        D = np.linalg.norm(q, axis=1)
        u = q / np.where(D > 0.0, D, 1.0)[:, None]
        inside = np.all(u @ self.normals.T >= 0.0, axis=1) | (D == 0.0)
        # Angle to the frustum: to a corner ray, or to the nearest point of a face (the
        # wedge between two corner rays) when the projection onto its plane lies in it.
        best = np.min(np.arccos(np.clip(u @ self.dirs.T, -1.0, 1.0)), axis=1)
        for i in range(4):
            n = self.normals[i]
            un = u @ n
            proj = u - un[:, None] * n
            norm = np.linalg.norm(proj, axis=1)
            ok = (norm > 0.0) & (proj @ self.wedge_a[i] >= 0.0) & (proj @ self.wedge_b[i] >= 0.0)
            angle = np.arctan2(np.abs(un), norm)
            best = np.where(ok, np.minimum(best, angle), best)
        behind = ~inside & (best >= 0.5 * math.pi)
        h = np.where(behind, D, D * np.sin(np.minimum(best, 0.5 * math.pi)))
        return np.where(inside, 0.0, h), behind

    def start_distances(self, points):
        """(least, largest), each (N,): distances from each world point to a ray start."""
        q = self.local(points)
        far = np.max(np.linalg.norm(q[:, None, :] - self.near_corners[None, :, :], axis=2), axis=1)
        if not self.ortho and self.clip_start == 0.0:
            D = np.linalg.norm(q, axis=1)
            return D, D
        # Ray starts fill the near plane's frame rectangle: its nearest point to q.
        xs, ys = self.near_corners[:, 0], self.near_corners[:, 1]
        nearest = np.column_stack([np.clip(q[:, 0], xs.min(), xs.max()), np.clip(q[:, 1], ys.min(), ys.max()),
                                   np.full(len(q), -self.clip_start)])
        return np.linalg.norm(q - nearest, axis=1), far


def point_bounds(frame, positions, I0, sigma, albedo, p_min, p_max, spot=False):
    """(upper, lower), each (N, 3) RGB, for N point lights (positions (N, 3), I0 (N, 3)
    W/sr); _spot_ (bool or (N,)): spot lights, whose lower bound is 0."""
    positions = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    w = np.asarray(albedo, dtype=np.float64) * np.asarray(I0, dtype=np.float64).reshape(-1, 3)
    n = len(positions)
    if sigma <= 0.0 or n == 0:
        return np.zeros((n, 3)), np.zeros((n, 3))
    h, behind = frame.ray_distances(positions)
    d_min, d_max = frame.start_distances(positions)
    with np.errstate(divide='ignore', over='ignore', invalid='ignore'):
        line = sigma * math.pi * np.exp(-sigma * d_min) / h * np.where(behind, 0.5, 1.0)
        direct = np.exp(-sigma * h) / (h * h)
        scale = np.where(h > 0.0, p_max * np.minimum(line, direct), math.inf)
    upper = np.where(w > 0.0, w * scale[:, None], 0.0)
    lower = w * (p_min * E2 * np.exp(-sigma * d_max) / (d_max + 1.0 / sigma) ** 2)[:, None]
    lower = np.where(np.broadcast_to(np.asarray(spot), (n,))[:, None], 0.0, lower)
    return upper, lower


def sun_bounds(E, sigma, albedo, p_min, p_max, layered):
    """(upper, lower), each (N, 3), for N sun lamps of irradiance E (N, 3) (sunlight_layer.h)."""
    w = np.asarray(albedo, dtype=np.float64) * np.asarray(E, dtype=np.float64).reshape(-1, 3)
    if sigma <= 0.0:
        return np.zeros_like(w), np.zeros_like(w)
    lower = np.zeros_like(w) if layered else w * (p_min * (1.0 - math.exp(-1.0)))
    return w * p_max, lower


def box_distances(points, boxes):
    """(N,) least distance from each of N points to the union of axis-aligned boxes ((K, 2, 3)
    lo, hi); inf with no box, 0 inside one."""
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if len(boxes) == 0:
        return np.full(len(points), math.inf)
    b = np.asarray(boxes, dtype=np.float64).reshape(-1, 2, 3)
    gap = np.maximum(0.0, np.maximum(b[None, :, 0, :] - points[:, None, :], points[:, None, :] - b[None, :, 1, :]))
    return np.sqrt(np.min(np.sum(gap * gap, axis=2), axis=1))


def shadow_bounds(positions, I0, sigma, albedo, p_max, casters):
    """(N, 3) upper bounds of the airlight a shadow can take from any pixel, for N point or
    spot lights (positions (N, 3), I0 (N, 3)) and the casters' bounding boxes. A shadow only
    darkens points farther from the light than the nearest caster, r: along any ray the
    points with d(x) >= r give int dt / d^2 <= pi / r and their light crossed at least r of
    fog, so La_shadowed <= omega sigma p_max I0 pi e^{-sigma r} / r (inf for a light inside a
    caster's box)."""
    r = box_distances(positions, casters)
    w = np.asarray(albedo, dtype=np.float64) * np.asarray(I0, dtype=np.float64).reshape(-1, 3)
    with np.errstate(divide='ignore', over='ignore', invalid='ignore'):
        scale = np.where(r > 0.0, sigma * p_max * math.pi * np.exp(-sigma * r) / r, math.inf)
    return np.where(w > 0.0, w * scale[:, None], 0.0)


def skip_faint(uppers, lowers, target, spent=None):
    """Bool mask (N,) of the lights to skip: the faintest (by upper bound) while the sum of
    the skipped upper bounds stays <= target * (sum of all lower bounds) in every channel,
    less _spent_ ((3,): what other approximations already took of that budget)."""
    uppers = np.asarray(uppers, dtype=np.float64).reshape(-1, 3)
    skip = np.zeros(len(uppers), dtype=bool)
    if len(uppers) == 0:
        return skip
    budget = target * np.sum(np.asarray(lowers, dtype=np.float64).reshape(-1, 3), axis=0)
    if spent is not None:
        budget = budget - np.asarray(spent, dtype=np.float64)
    order = np.argsort(np.max(uppers, axis=1), kind="stable")
    with np.errstate(invalid='ignore'):
        cumulative = np.cumsum(uppers[order], axis=0)
    fits = np.all(np.isfinite(cumulative) & (cumulative <= budget), axis=1)
    n_skip = len(fits) if fits.all() else int(np.argmin(fits))
    skip[order[:n_skip]] = True
    return skip
