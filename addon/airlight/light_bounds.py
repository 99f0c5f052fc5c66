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
    space (Blender's camera.view_frame(scene), counter-clockwise or clockwise), whether it is
    orthographic, and the near clip distance along the view axis."""

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
        else:
            dirs = c / -c[:, 2:3]                      # scaled to unit view-axis depth
            self.dirs = dirs / np.linalg.norm(dirs, axis=1, keepdims=True)
            self.near_corners = dirs * self.clip_start
            centre = self.dirs.sum(axis=0)
            self.normals = []
            for i in range(4):
                n = np.cross(self.dirs[i], self.dirs[(i + 1) % 4])
                n /= np.linalg.norm(n)
                self.normals.append(n if n @ centre >= 0.0 else -n)   # pointing into the frustum

    def local(self, p):
        """World point -> camera space."""
        return self.rot.T @ (np.asarray(p, dtype=np.float64) - self.eye)

    def ray_distance(self, p):
        """(h, behind): the least distance from the world point p to a camera ray's line (0
        inside the frame), and whether p is at least 90 deg from every ray (then h is its
        distance to the eye, and the bound's half-line form applies)."""
        q = self.local(p)
        if self.ortho:
            dx = max(self.xmin - q[0], 0.0, q[0] - self.xmax)
            dy = max(self.ymin - q[1], 0.0, q[1] - self.ymax)
            return math.hypot(dx, dy), False
        D = float(np.linalg.norm(q))
        if D == 0.0:
            return 0.0, False
        u = q / D
        if all(float(n @ u) >= 0.0 for n in self.normals):
            return 0.0, False
        # Angle to the frustum's boundary: the nearest point on one of its 4 faces (each a
        # wedge between two corner rays), or a corner ray itself.
        best = min(math.acos(min(1.0, max(-1.0, float(u @ c)))) for c in self.dirs)
        for i in range(4):
            a, b = self.dirs[i], self.dirs[(i + 1) % 4]
            n = self.normals[i]
            proj = u - (u @ n) * n
            norm = float(np.linalg.norm(proj))
            if norm == 0.0:
                continue
            proj /= norm
            # Inside the wedge between a and b (the short arc)?
            if np.cross(a, proj) @ np.cross(a, b) >= 0.0 and np.cross(proj, b) @ np.cross(a, b) >= 0.0:
                best = min(best, math.atan2(abs(float(u @ n)), float(u @ proj)))
        if best >= 0.5 * math.pi:
            return D, True
        return D * math.sin(best), False

    def start_distances(self, p):
        """(least, largest) distance from the world point p to a camera ray's start."""
        q = self.local(p)
        far = max(float(np.linalg.norm(q - c)) for c in self.near_corners)
        if self.ortho:
            near_plane_q = np.array([min(max(q[0], self.xmin), self.xmax), min(max(q[1], self.ymin), self.ymax),
                                     -self.clip_start])
            return float(np.linalg.norm(q - near_plane_q)), far
        if self.clip_start == 0.0:
            D = float(np.linalg.norm(q))
            return D, D
        # Ray starts lie on the near plane's frame rectangle: its nearest point to q.
        z = -self.clip_start
        xs, ys = self.near_corners[:, 0], self.near_corners[:, 1]
        nearest = np.array([min(max(q[0], xs.min()), xs.max()), min(max(q[1], ys.min()), ys.max()), z])
        return float(np.linalg.norm(q - nearest)), far


def point_bounds(frame, position, I0, sigma, albedo, p_min, p_max, spot=False):
    """(upper, lower) RGB bounds of a point (or spot: lower 0) light's airlight over the frame."""
    I0 = np.asarray(I0, dtype=np.float64)
    w = np.asarray(albedo, dtype=np.float64) * I0
    if sigma <= 0.0 or not np.any(w > 0.0):
        return np.zeros(3), np.zeros(3)
    h, behind = frame.ray_distance(position)
    d_min, d_max = frame.start_distances(position)
    if h == 0.0:
        upper = np.full(3, math.inf)
    else:
        line = sigma * math.pi * math.exp(-sigma * d_min) / h * (0.5 if behind else 1.0)
        upper = w * (p_max * min(line, math.exp(-sigma * h) / (h * h)))
    upper = np.where(w > 0.0, upper, 0.0)
    if spot:
        return upper, np.zeros(3)
    lower = w * (p_min * E2 * math.exp(-sigma * d_max) / (d_max + 1.0 / sigma) ** 2)
    return upper, lower


def sun_bounds(E, sigma, albedo, p_min, p_max, layered):
    """(upper, lower) RGB bounds of a sun lamp's airlight (sun_layer.h)."""
    w = np.asarray(albedo, dtype=np.float64) * np.asarray(E, dtype=np.float64)
    if sigma <= 0.0:
        return np.zeros(3), np.zeros(3)
    lower = np.zeros(3) if layered else w * (p_min * (1.0 - math.exp(-1.0)))
    return w * p_max, lower


def skip_faint(uppers, lowers, target):
    """Indices of lights to skip: the faintest (by upper bound) while the sum of the
    skipped upper bounds stays <= target * (sum of all lower bounds) in every channel."""
    if not uppers:
        return set()
    budget = target * np.sum(np.asarray(lowers, dtype=np.float64), axis=0)
    order = sorted(range(len(uppers)), key=lambda i: float(np.max(uppers[i])))
    used = np.zeros(3)
    skipped = set()
    for i in order:
        u = np.asarray(uppers[i], dtype=np.float64)
        if not np.all(np.isfinite(u)) or not np.all(used + u <= budget):
            break
        used += u
        skipped.add(i)
    return skipped
