"""Soft shadows: how many points of a lamp's sphere cast its volumetric shadows.

A point or spot light with a Radius, and a sun with an Angle, cast soft shadows in Cycles.
The bake casts them from `shadow_samples` points of the light's sphere (native
sphere_light_shadow_samples) or directions over the sun's disk (sun_shadow_directions), one
shadow volume each, and lights the fog by their mean: each sample costs about one more
shadowed bake. Soft Shadow Samples *Automatic* (0) measures, per frame, what the samples
change, on probe bakes of the frame at about PROBE_PIXELS pixels (the same view, no edge
sub-samples):
- hard shadows (1 sample) when they differ from FIRST_CHECK samples' by at most MARGIN of the
  target (mean relative difference over the lit fog): the common case, a small Radius, costs
  the probe's 1 + FIRST_CHECK samples;
- else the first count n of LADDER whose bake differs from 2n's by at most MARGIN of the
  target, else the last. The samples converge about as 1/n (docs/models.md), so n's error is
  about twice its difference from 2n's: MARGIN = 1/2 puts it at the target.
Lights with no Radius or Angle, no shadows, or fog objects (whose lights are points) need no
probe: one sample, the centre. Where the casters make shadow samples dear, the probe stops at
PROBE_BUDGET and says so (Choice.limited): hard shadows, or the finest count it measured. The
budget counts the probe's own work (the calling thread's CPU time, its share of the bake's
threads), not the wall clock: beside a render engine, at the lowest priority, the probe's
bakes wait for the engine, and the count must not depend on how long they waited.
Street at 1080p, 0.25 m lamps: the probe adds ~0.08 s to a 0.64 s bake.

A count measured to its end (not cut short by the budget, which depends on the machine's
speed) is kept in the table cache's folder (native.table_cache_dir) under a digest of
everything the probe bakes from (the view, lights, casters, settings and target) and this
module's rules, and taken from there for the same frame (Choice.remembered): a still rendered
again, or a locked-off shot's frames on a farm, do not measure it again.
"""

import hashlib
import math
import time
from collections import namedtuple

import numpy as np

# The counts Automatic takes. 2 and 4 samples band the penumbra more than the hard shadow
# errs (measured worse than 1 on test_bake_soft_shadows.py's slit), so the ladder starts at 8.
FIRST_CHECK = 16
LADDER = (8, 16, 32, 64)
# The probe's size: ~1/14 of a 1080p frame's width and height.
PROBE_PIXELS = 10000
# The share of the target a count's measured difference may take.
MARGIN = 0.5
# The most the probe may take, in seconds of its own work (foreseen from its first bake): a
# 2-million-triangle caster made a shadow sample cost ~2 s at the probe's size, so that
# measuring 16 would have taken 34 s for a 3 s bake.
PROBE_BUDGET = 3.0
# A shadow sample's cost per caster triangle and soft-shadowed light (its volume's
# silhouettes and faces), measured on that plane: 2e6 triangles, one light, ~2 s a sample; a
# 1e5-triangle grid over the street's 4 lamps, 5.4 s for 16 samples at the probe's size. Casters
# so many that the probe's first two bakes would pass the budget are not probed at all (the
# first bake's own time cannot tell: it shares the frame's volumes once they are built).
SAMPLE_SECONDS_PER_TRIANGLE = 1e-6
# Pixels whose reference airlight is below this share of its 99th percentile are not
# weighed (no fog to speak of), and relative errors are taken against at least it.
FLOOR = 0.01


def needed(description):
    """Whether any baked light of _description_ (`_native.bake`'s scene arguments) casts soft
    shadows: shadows on, a point light or spot with a Radius or a sun with an Angle, with its
    shadow flag, and no fog objects."""
    return soft_lights(description) > 0


def soft_lights(description):
    """How many baked lights of _description_ cast soft shadows (needed())."""
    if not description.get("shadows") or len(description.get("rbf_centres", ())) > 0:
        return 0
    count = 0
    for radii, flags in (("light_radii", "light_shadows"), ("spot_radii", "spot_shadows"),
                         ("sun_angles", "sun_shadows")):
        r = np.asarray(description.get(radii, ()), dtype=np.float64).ravel()
        if r.size == 0:
            continue
        f = description.get(flags)
        f = np.ones_like(r) if f is None else np.asarray(f, dtype=np.float64).ravel()
        count += int(np.count_nonzero((r > 0.0) & (f != 0.0)))
    return count


def probe_description(description):
    """_description_ at about PROBE_PIXELS pixels (no more than it has; at least 16 on a
    side): the same camera and projection, so the same view on fewer pixels."""
    width, height = int(description["width"]), int(description["height"])
    scale = max(1.0, (width * height / PROBE_PIXELS) ** 0.5)
    out = dict(description)
    out["width"], out["height"] = max(16, round(width / scale)), max(16, round(height / scale))
    return out


def mean_error(airlight, reference):
    """Mean relative difference of _airlight_ from _reference_ (H x W x 3) over the lit fog:
    the pixels whose reference sum is above FLOOR of its 99th percentile."""
    a, ref = np.sum(airlight, axis=-1, dtype=np.float64), np.sum(reference, axis=-1, dtype=np.float64)
    floor = FLOOR * float(np.percentile(ref, 99)) if ref.size else 0.0
    lit = ref > floor
    if floor <= 0.0 or not lit.any():
        return 0.0
    return float(np.mean(np.abs(a[lit] - ref[lit]) / ref[lit]))


Choice = namedtuple("Choice", "samples error seconds limited remembered", defaults=(False,))
Choice.__doc__ = """Soft Shadow Samples Automatic's count (penumbra.choose): _samples_; _error_ the
mean relative difference measured between it and the finer count it was checked against
(nan where none was); _seconds_ the probe's; _limited_ why the target was not met: '' (it
was), 'budget' (PROBE_BUDGET cut the measuring short: the finest count measured, or hard
shadows) or 'ladder' (the last count, whose coarser neighbour still differed from it by
_error_); _remembered_: taken from an earlier measure of the same frame (the module's
docstring), _error_ as measured then."""

# How a kept record spells Choice.limited (a 'budget' choice is not kept).
_LIMITS = ("", "ladder")


def choose(module, description, settings, target):
    """The Choice for _target_ (relative): see the module's docstring. _settings_:
    `_native.bake`'s other keyword arguments. Each probe bake of n samples is foreseen to cost
    n times the first's (one shadow volume each: heavy casters make them dear); one that would
    take the probe past PROBE_BUDGET seconds is not baked, nor any where the casters' triangle
    count times the soft-shadowed lights' foretells it (SAMPLE_SECONDS_PER_TRIANGLE)."""
    start, work_start = time.perf_counter(), time.thread_time()
    casters = len(description.get("occluder_triangles", description.get("triangles", ())))
    foretold = casters * max(1, soft_lights(description)) * SAMPLE_SECONDS_PER_TRIANGLE
    if (1 + FIRST_CHECK) * foretold > PROBE_BUDGET:
        return Choice(1, math.nan, time.perf_counter() - start, "budget")
    probe = probe_description(description)
    # The airlight alone: no surface passes, per-light passes or edge sub-samples.
    args = {k: v for k, v in settings.items()
            if k not in ("shadow_samples", "light_pass_index") and not k.startswith("surface")}
    args["aa_samples"] = 1
    key = _record_key(probe, args, target)
    kept = _kept(module, key)
    if kept is not None:
        return kept._replace(seconds=time.perf_counter() - start)
    choice = _measure(module, probe, args, target, start, work_start)
    _keep(module, key, choice)
    return choice


def _measure(module, probe, args, target, start, work_start):
    """choose()'s measuring: the probe bakes of _probe_ with _args_ (started at _start_,
    perf_counter, and _work_start_, thread_time)."""
    bakes = {}

    def airlight(samples):
        if samples not in bakes:
            bakes[samples] = module.bake(**probe, **args, shadow_samples=samples)["airlight"]
        return bakes[samples]

    def work():
        # Seconds of the probe's work at full speed: the calling thread takes its share of
        # every bake's items (core/parallel.h), so its CPU time is about the bakes' wall time
        # on an idle machine, and does not grow while they wait for other threads.
        return time.thread_time() - work_start

    def affordable(samples):
        return samples in bakes or work() + samples * per_sample <= PROBE_BUDGET

    airlight(1)
    per_sample = work()

    def done(samples, error, limited=""):
        return Choice(samples, error, time.perf_counter() - start, limited)
    if not affordable(FIRST_CHECK):
        return done(1, math.nan, "budget")
    error = mean_error(airlight(1), airlight(FIRST_CHECK))
    if error <= MARGIN * target:
        return done(1, error)
    for coarse, fine in zip(LADDER, LADDER[1:]):
        if not (affordable(coarse) and affordable(fine)):
            return done(max(bakes), error, "budget")
        error = mean_error(airlight(coarse), airlight(fine))
        if error <= MARGIN * target:
            return done(coarse, error)
    return done(LADDER[-1], error, "ladder")


def _record_key(probe, args, target):
    """The key a Choice for the probe bakes of _probe_ with _args_ and _target_ is kept under:
    this module's rules and a digest of every argument (arrays by type, shape and bytes)."""
    digest = hashlib.blake2b(digest_size=20)
    for kind, values in (("scene", probe), ("settings", args)):
        for name in sorted(values):
            value = values[name]
            array = np.ascontiguousarray(value) if isinstance(value, (np.ndarray, list, tuple)) else None
            if array is not None and array.dtype != object:
                digest.update(f"{kind}.{name}:{array.dtype.str}{array.shape}:".encode())
                digest.update(array.tobytes())
            else:  # (a scalar, a string; objects by their repr, never their addresses)
                digest.update(f"{kind}.{name}={value!r};".encode())
    return (f"penumbra.choose 1: first check {FIRST_CHECK}, ladder {LADDER}, margin {MARGIN!r}, "
            f"floor {FLOOR!r}, target {float(target)!r}, arguments {digest.hexdigest()}")


def _kept(module, key):
    """The Choice kept under _key_ (remembered), or None."""
    record = getattr(module, "table_cache_record", None)
    values = record(key, 3) if record is not None else None
    if values is None:
        return None
    samples, error, limited = int(values[0]), float(values[1]), int(values[2])
    if samples not in (1,) + LADDER or not 0 <= limited < len(_LIMITS):
        return None
    return Choice(samples, error, 0.0, _LIMITS[limited], True)


def _keep(module, key, choice):
    """Keeps _choice_ under _key_ unless the budget cut it short (that depends on the
    machine's speed, not on the frame)."""
    store = getattr(module, "table_cache_store_record", None)
    if store is not None and choice.limited in _LIMITS:
        store(key, np.array([choice.samples, choice.error, _LIMITS.index(choice.limited)], np.float64))
