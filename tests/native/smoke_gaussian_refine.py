"""Smoke test of the WIP refinement: a thick Gaussian around a point light, Fogshop alone,
refined at 1 %, and QUADRATURE (the reference)."""
import sys, math, time
import numpy as np
import os; sys.path[:0] = [sys.argv[1], os.path.dirname(os.path.abspath(__file__))]
import _native
from scene_util import camera_matrix, perspective, plane_y, rotation_x
from reference_util import rel_errors
W, H = 32, 24
def bake(**kw):
    v, t = plane_y(-3.0, x=(-300.0, 300.0), z=(1.0, -200.0))
    b = np.array([[0.3, 0.2, -15.0], [-3.0, 0.5, -17.0], [3.5, -0.5, -14.0]])
    a = np.array([0.5, 0.4, 0.6]); c = np.array([5 * 0.5 / math.sqrt(math.pi), 0.2, 0.3])
    args = dict(width=W, height=H, cam_to_world=camera_matrix(rotation_x(0.0), np.zeros(3)),
                projection=perspective(math.radians(60), W, H), vertices=v, triangles=t,
                light_positions=np.array([[0.0, 0.0, -15.0]]), light_intensities=np.array([[100.0, 80.0, 60.0]]),
                sigma_t=float(__import__("os").environ.get("S","0.01")), albedo=(0.9, 0.8, 0.7), clip_start=0.5, threads=2, aa_samples=1,
                rbf_centres=b, rbf_scales=a, rbf_amplitudes=c)
    args.update(kw)
    return _native.bake(**args)
ref = bake(model="quadrature")
for acc in (0.0, 0.05, 0.01, 0.001):
    t = time.perf_counter(); r = bake(gaussian_accuracy=acc); dt = time.perf_counter() - t
    e = rel_errors(r["airlight"], ref["airlight"])
    s = r["stats"]
    print(f"acc {acc}: mean {e.mean():.4f} p99 {np.percentile(e, 99):.4f} max {e.max():.4f} "
          f"pairs {s['gaussian_pairs']} refined {s['gaussian_refined_pairs']} kept {s['gaussian_kept_bound']:.3g} {dt:.2f}s")
