"""A slow pure-numpy stand-in for `_native`, for developing the add-on before the
C++ module exists (tests/blender/conftest.py installs it only when AIRLIGHT_FAKE_NATIVE=1
and the real module cannot be imported).

It follows the `_native` contract: pixel-centre rays only (no edge supersampling),
brute-force ray/triangle intersection, airlight by Gauss-Legendre quadrature of the
single-scattering integral  sum_l  sigma_s I0_l / (4 pi) * exp(-sigma_t (t + d_l(t))) / d_l(t)^2  dt.
Never use it as a reference for the native module's numbers.
"""

import math

import numpy as np

__version__ = "fake-0"


class BakeCancelled(Exception):
    pass


def models():
    return [("sun05", "fake"), ("sun05_exact", "fake"), ("quadrature", "fake")]


def _rays(width, height, cam_to_world, projection):
    j, i = np.mgrid[0:height, 0:width]
    x = 2.0 * (i + 0.5) / width - 1.0
    y = 1.0 - 2.0 * (j + 0.5) / height
    inv = np.linalg.inv(projection)
    near = np.stack([x, y, -np.ones_like(x), np.ones_like(x)], -1) @ inv.T
    far = np.stack([x, y, np.ones_like(x), np.ones_like(x)], -1) @ inv.T
    near = near[..., :3] / near[..., 3:]
    far = far[..., :3] / far[..., 3:]
    d_cam = far - near
    d = d_cam @ cam_to_world[:3, :3].T
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    o = np.broadcast_to(cam_to_world[:3, 3], d.shape)
    return o.reshape(-1, 3), d.reshape(-1, 3)


def _intersect(o, d, vertices, triangles):
    t_hit = np.full(len(o), np.inf)
    if len(triangles) == 0:
        return t_hit
    v = vertices.astype(np.float64)
    v0, v1, v2 = v[triangles[:, 0]], v[triangles[:, 1]], v[triangles[:, 2]]
    e1, e2 = v1 - v0, v2 - v0
    for start in range(0, len(o), 4096):
        oo, dd = o[start:start + 4096, None, :], d[start:start + 4096, None, :]
        p = np.cross(dd, e2[None])
        det = np.sum(e1[None] * p, -1)
        with np.errstate(divide="ignore", invalid="ignore"):
            inv_det = 1.0 / det
            s = oo - v0[None]
            u = np.sum(s * p, -1) * inv_det
            q = np.cross(s, e1[None])
            w = np.sum(dd * q, -1) * inv_det
            t = np.sum(e2[None] * q, -1) * inv_det
        ok = (np.abs(det) > 1e-12) & (u >= 0) & (w >= 0) & (u + w <= 1) & (t > 1e-6)
        t = np.where(ok, t, np.inf)
        t_hit[start:start + 4096] = t.min(axis=1)
    return t_hit


def bake(*, width, height, cam_to_world, projection, vertices, triangles, light_positions,
         light_intensities, sigma_t, albedo=(1, 1, 1), model="sun05", threads=0,
         aa_samples=4, filter_width=1.5, progress=None):
    if width <= 0 or height <= 0:
        raise ValueError("resolution must be positive")
    if not math.isfinite(sigma_t) or sigma_t < 0:
        raise ValueError("sigma_t must be finite and >= 0")
    cam_to_world = np.asarray(cam_to_world, np.float64)
    projection = np.asarray(projection, np.float64)
    vertices = np.asarray(vertices, np.float32).reshape(-1, 3)
    triangles = np.asarray(triangles, np.uint32).reshape(-1, 3).astype(np.int64)
    lp = np.asarray(light_positions, np.float64).reshape(-1, 3)
    li = np.asarray(light_intensities, np.float64).reshape(-1, 3)
    o, d = _rays(width, height, cam_to_world, projection)
    t_hit = _intersect(o, d, vertices, triangles)
    if progress is not None and progress(0.5) is False:
        raise BakeCancelled("bake cancelled")
    T = np.exp(-sigma_t * t_hit)
    t_max = np.minimum(t_hit, 60.0 / max(sigma_t, 1e-3))
    xg, wg = np.polynomial.legendre.leggauss(64)
    airlight = np.zeros((len(o), 3))
    n_seg = 16
    for k in range(n_seg):
        a, b = t_max * k / n_seg, t_max * (k + 1) / n_seg
        ts = 0.5 * (b - a)[:, None] * (xg[None] + 1) + a[:, None]
        ws = 0.5 * (b - a)[:, None] * wg[None]
        x = o[:, None, :] + d[:, None, :] * ts[..., None]
        for p, I0 in zip(lp, li):
            r2 = np.sum((x - p) ** 2, -1)
            f = np.exp(-sigma_t * (ts + np.sqrt(r2))) / r2 * sigma_t / (4 * math.pi)
            airlight += np.sum(f * ws, 1)[:, None] * I0[None]
    airlight *= np.asarray(albedo, np.float64)[None]
    if progress is not None and progress(1.0) is False:
        raise BakeCancelled("bake cancelled")
    return dict(
        airlight=airlight.reshape(height, width, 3).astype(np.float32),
        transmittance=np.repeat(T.reshape(height, width, 1), 3, -1).astype(np.float32),
        depth=t_hit.reshape(height, width).astype(np.float32),
        stats=dict(seconds_raycast=0.0, seconds_airlight=0.0, supersampled_pixels=0,
                   samples=width * height),
    )


def write_exr(path, passes, layer_prefix=""):
    import OpenImageIO as oiio
    names = list(passes)
    h, w, _ = passes[names[0]].shape
    data = np.concatenate([np.asarray(passes[n], np.float32) for n in names], -1)
    spec = oiio.ImageSpec(w, h, 3 * len(names), oiio.FLOAT)
    spec.channelnames = tuple(f"{layer_prefix}{n}.{c}" for n in names for c in "RGB")
    spec.attribute("compression", "zip")
    out = oiio.ImageOutput.create(path)
    if out is None or not out.open(path, spec) or not out.write_image(data):
        raise RuntimeError(f"cannot write {path}: {oiio.geterror()}")
    out.close()
