"""The bake at the extremes of what Blender allows, fuzzed: cameras (clip range, focal length,
sensor fit, shift, orthographic scale, resolution, pixel aspect), the scene's scale, the fog's
density and anisotropy. Every case must bake without killing Blender, in bounded time, with
finite passes in range, and where a Cycles render is cheap with its silhouettes on Cycles'.

The bakes run in a child Blender (support/extremes_child.py), so an abort fails this test
and names the case instead of taking the whole run down; after a crash the child is started
again on the cases left. The cases come from a seeded generator (AIRLIGHT_FUZZ_SEED picks
another draw, AIRLIGHT_FUZZ_CASES how many) plus the corners that broke before: Clip Start 0.001 m with Clip End 100 km,
Clip Start 1e-6 m with Clip End 100 m, thick fog with Surface Shading.
"""
import json
import math
import os
import random

import numpy as np
import pytest

from conftest import BLENDER_SH, HERE

CHILD = os.path.join(HERE, "support", "extremes_child.py")
SECONDS_PER_BAKE = 20.0  # a 64 x 48 bake takes ~0.1 s; first use of a table ~1-3 s
PHASES = [("HENYEY_GREENSTEIN", 0.0), ("HENYEY_GREENSTEIN", 0.6), ("HENYEY_GREENSTEIN", -0.99),
          ("HENYEY_GREENSTEIN", 0.99), ("RAYLEIGH", 0.0), ("MIE_HAZY", 0.0)]


def log_uniform(rng, lo, hi):
    return math.exp(rng.uniform(math.log(lo), math.log(hi)))


def make_case(rng, index):
    ortho = rng.random() < 0.3
    clip_start = log_uniform(rng, 1e-6, 1e3)
    clip_end = min(1e9, clip_start * log_uniform(rng, 2.0, 1e15))
    depth = math.sqrt(clip_start * clip_end) if rng.random() < 0.5 else clip_start * log_uniform(rng, 1.5, 30.0)
    depth = min(depth, clip_end / 1.5)
    # (Blender's smallest resolution is 4 px; 1 x 1 comes from 100 x 100 at 1 %: "percentage".)
    res = rng.choice([(64, 48), (48, 64), (37, 23), (100, 100, 1), (8192, 4), (4, 700), (96, 4), (33, 33)])
    aspect = rng.choice([(1.0, 1.0), (1.0, 1.0), (3.0, 1.0), (1.0, 7.5), (200.0, 1.0)])
    phase, g = rng.choice(PHASES)
    return {
        "id": index,
        "camera": {
            "type": 'ORTHO' if ortho else 'PERSP',
            "lens": log_uniform(rng, 1.0, 5000.0),
            "sensor_fit": rng.choice(['AUTO', 'HORIZONTAL', 'VERTICAL']),
            "shift": [rng.uniform(-2.0, 2.0), rng.uniform(-2.0, 2.0)],
            "ortho_scale": log_uniform(rng, 1e-4, 1e6),
            "clip": [clip_start, clip_end],
        },
        "res": list(res[:2]),
        "percentage": res[2] if len(res) > 2 else 100,
        "aspect": list(aspect),
        "origin": rng.choice([[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [1e6, -1e6, 3.0]]),
        "depth": depth,
        "empty": rng.random() < 0.1,
        "sun": rng.random() < 0.2,
        "spot": rng.random() < 0.3,
        "fog": {
            "model": rng.choice(['AUTO'] * 6 + ['SUN05_EXACT', 'BIRI06', 'PEGORARO10', 'QUADRATURE', 'BASELINE']),
            "density": log_uniform(rng, 1e-9, 1e4),
            "phase": phase,
            "g": g,
            "surface": rng.random() < 0.6,
            "environment": rng.random() < 0.3,
        },
    }


def corner(index, clip, density=0.05, surface=False, empty=False, cycles=True, res=(64, 48), percentage=100,
           **camera):
    cam = {"type": 'PERSP', "lens": 50.0, "sensor_fit": 'AUTO', "shift": [0.0, 0.0], "ortho_scale": 6.0,
           "clip": list(clip)}
    cam.update(camera)
    depth = min(max(10.0, 3.0 * clip[0]), clip[1] / 1.5)
    return {"id": index, "camera": cam, "res": list(res), "percentage": percentage, "aspect": [1.0, 1.0],
            "origin": [0.0, 0.0, 0.0],
            "depth": depth, "empty": empty, "sun": False, "spot": False, "cycles": cycles and not empty,
            "fog": {"model": 'AUTO', "density": density, "phase": "HENYEY_GREENSTEIN", "g": 0.0, "surface": surface,
                    "environment": False}}


def make_cases(seed, n_random=60):
    """The corners that broke before, a few more, then _n_random_ seeded draws; every case
    with a resolution of at most 64 x 64 and a moderate pixel aspect among the first draws
    gets a Cycles silhouette check (six in all, the corners aside)."""
    cases = [
        corner(0, (0.001, 1e5)),                      # aborted Blender (Embree assertion)
        corner(1, (0.001, 1e5), empty=True),          # composited a black frame
        corner(2, (1e-6, 100.0)),                     # aborted Blender
        corner(3, (1e-6, 1e9), shift_x=2.0, shift_y=-2.0, sensor_fit='VERTICAL'),
        corner(4, (0.1, 100.0), density=5.0, surface=True, cycles=False),    # stalled > 60 s
        corner(5, (0.1, 100.0), density=1e4, surface=True, cycles=False),    # stalled > 300 s
        corner(6, (0.1, 1e9), type='ORTHO', ortho_scale=1e-4),
        corner(7, (1e-6, 1e9), type='ORTHO', ortho_scale=1e6),
        corner(8, (0.1, 1000.0), lens=1.0),
        corner(9, (0.1, 1e6), lens=5000.0),
        corner(10, (0.1, 100.0), res=(100, 100), percentage=1, cycles=False),
        corner(11, (0.1, 100.0), res=(8192, 4), cycles=False),
    ]
    rng = random.Random(seed)
    cycles_left = 6
    for k in range(n_random):
        case = make_case(rng, len(cases))
        small = case["res"][0] * case["res"][1] <= 64 * 64 and max(case["aspect"]) <= 7.5
        # Single-precision geometry (Blender's, Cycles', Embree's) places a vertex at 1e6 m to
        # 0.06 m: silhouettes are compared only where the slab is far larger than that.
        precise = case["depth"] > 1e-4 * max(abs(x) for x in case["origin"]) if any(case["origin"]) else True
        case["cycles"] = bool(small and precise and not case["empty"] and cycles_left > 0)
        cycles_left -= case["cycles"]
        cases.append(case)
    return cases


def run_child(cases, tmp_path, timeout):
    """Runs the child over _cases_ until every case has a result, restarting it after a
    crash; returns {id: result}, crashed cases as {"status": "crashed", "output": ...}."""
    import subprocess
    results = {}
    results_path = tmp_path / "results.jsonl"
    left = list(cases)
    while left:
        cases_path = tmp_path / "cases.json"
        cases_path.write_text(json.dumps(left))
        proc = subprocess.run([BLENDER_SH, "-b", "--python", CHILD, "--", str(cases_path), str(results_path),
                               str(tmp_path)], capture_output=True, text=True, timeout=timeout)
        started = None
        for line in results_path.read_text().splitlines():
            record = json.loads(line)
            if record["status"] == "started":
                started = record["id"]
            else:
                results[record["id"]] = record
                started = None
        if started is not None and started not in results:
            results[started] = {"id": started, "status": "crashed", "returncode": proc.returncode,
                                "output": (proc.stdout + proc.stderr)[-2000:]}
        elif proc.returncode != 0 and all(c["id"] in results for c in left):
            pass  # every case done; the exit code is checked by the cases' results
        elif proc.returncode != 0 and started is None:
            pytest.fail(f"the child Blender failed before its first case:\n{(proc.stdout + proc.stderr)[-3000:]}")
        left = [c for c in left if c["id"] not in results]
    return results


def describe(case):
    c = case["camera"]
    return (f"case {case['id']}: {c['type']} lens {c['lens']:.4g} fit {c['sensor_fit']} shift "
            f"{c['shift'][0]:.2f},{c['shift'][1]:.2f} ortho {c['ortho_scale']:.3g} clip {c['clip'][0]:.3g}.."
            f"{c['clip'][1]:.3g}, {case['res'][0]}x{case['res'][1]} at {case['percentage']} % aspect "
            f"{case['aspect']}, origin "
            f"{case['origin']}, depth {case['depth']:.3g}{' empty' if case['empty'] else ''}"
            f"{' +sun' if case['sun'] else ''}{' +spot' if case['spot'] else ''}, {case['fog']['model']}, density "
            f"{case['fog']['density']:.3g} {case['fog']['phase']} g {case['fog']['g']}, surface "
            f"{case['fog']['surface']}, environment {case['fog']['environment']}")


def expected_refusal(case):
    """The model the case asks for cannot take its phase (a clear refusal is then right)."""
    fog = case["fog"]
    anisotropic = fog["phase"] != "HENYEY_GREENSTEIN" or fog["g"] != 0.0
    if fog["model"] in ('SUN05', 'SUN05_EXACT') and anisotropic:
        return "supports only the isotropic phase"
    if fog["model"] == 'PEGORARO10' and fog["phase"] == "HENYEY_GREENSTEIN" and abs(fog["g"]) > 0.78:
        return "needs a Legendre order above 96"
    return None


def silhouette_mismatch(hit, alpha):
    """Pixels the bake's centre rays and Cycles' coverage disagree on, away from silhouettes:
    a hit where Cycles' alpha < 0.01, or a miss where it is > 0.99."""
    return int(((hit > 0.5) & (alpha < 0.01)).sum() + ((hit < 0.5) & (alpha > 0.99)).sum())


def test_extremes_fuzz(tmp_path):
    seed = int(os.environ.get("AIRLIGHT_FUZZ_SEED", "2112"))
    cases = make_cases(seed, int(os.environ.get("AIRLIGHT_FUZZ_CASES", "60")))
    results = run_child(cases, tmp_path, timeout=600)
    failures = []
    for case in cases:
        r = results[case["id"]]
        what = describe(case)
        refusal = expected_refusal(case)
        if refusal is not None:
            if r["status"] != "refused" or refusal not in r.get("message", ""):
                failures.append(f"{what}: expected the refusal '{refusal}', got {r['status']}: {r.get('message')}")
            continue
        if r["status"] != "baked":
            failures.append(f"{what}: {r['status']}: {(r.get('message') or r.get('output', ''))[:600]}")
            continue
        if r["seconds"] > SECONDS_PER_BAKE:
            failures.append(f"{what}: took {r['seconds']:.1f} s")
        ok, lo, hi = r["airlight"]
        if not ok or lo < 0.0:
            failures.append(f"{what}: Airlight not finite or negative ({lo}, {hi})")
        ok, lo, hi = r["transmittance"]
        if not ok or lo < 0.0 or hi > 1.0 + 1e-6:
            failures.append(f"{what}: Transmittance outside [0, 1] ({lo}, {hi})")
        if r["surface"] is not None and not r["surface"][0]:
            failures.append(f"{what}: surface passes not finite")
        # (The lamp sits ~0.6 depth from the camera: only an optical depth of a few reaches it.)
        thin = 1e-3 < case["fog"]["density"] * case["depth"] < 20.0
        if case["empty"] and thin and case["camera"]["type"] == 'PERSP' and not r["airlight"][2] > 0.0:
            failures.append(f"{what}: a lamp in fog with no geometry gave no airlight")
        if r.get("cycles"):
            hit = np.load(tmp_path / f"hit_{case['id']}.npy")
            alpha = np.load(tmp_path / f"alpha_{case['id']}.npy")
            bad = silhouette_mismatch(hit, alpha)
            print(f"{what}: {bad} of {hit.size} pixels off Cycles' silhouettes, "
                  f"coverage {hit.mean():.2f} / {alpha.mean():.2f}")
            if bad > max(1, 0.005 * hit.size) or hit.sum() == 0:
                failures.append(f"{what}: {bad} pixels off Cycles' silhouettes (bake hits {int(hit.sum())}, "
                                f"Cycles covers {float(alpha.sum()):.1f})")
    assert not failures, "\n".join(failures)


def test_cases_cover_the_ranges():
    """The generator reaches the corners the issue names (so the fuzz test can fail there)."""
    cases = make_cases(2112)
    clips = [c["camera"]["clip"] for c in cases]
    assert min(c[0] for c in clips) <= 1e-6 and max(c[1] for c in clips) >= 1e9
    assert {c["camera"]["type"] for c in cases} == {'PERSP', 'ORTHO'}
    sizes = {(c["res"][0] * c["percentage"] // 100, c["res"][1] * c["percentage"] // 100) for c in cases}
    assert sizes >= {(1, 1), (8192, 4)}
    densities = [c["fog"]["density"] for c in cases]
    assert min(densities) < 1e-6 and max(densities) >= 1e4
    assert sum(c.get("cycles", False) for c in cases) >= 10
