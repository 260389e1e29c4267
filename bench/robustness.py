"""The robustness grid (issue 11): lifetime accuracy and noise against the simulator's truth, cell by cell, on Dask.

Each cell is one simulated scene (:mod:`evedge.sim`, exact per-event truth):

* ``stripes``: straight stripes (period 20 px, edge normal at ``angle_deg``)
  moving along their normal at ``speed`` px/s (truth lifetime ``1e6 / speed`` us);
* ``rotation``: a dark star rotating about its centre (speed grows with the radius);
* ``shapes``: a triangle, a square at 45 degrees and a disc translating diagonally.

The contrast ratio ``r = log-contrast / threshold`` sets the events per edge
and pixel (``r = 1.3``: one, sometimes two; ``r = 5``: five); background noise
is Poisson, ``noise_hz`` per pixel. Each method runs as the project's pipeline
(:func:`evedge.detector.pipeline.detect`: intra with the event buffer, Mueggler
without, as its original). Per cell and method, :func:`score` gives:

``med``         median |estimate / truth - 1| over signal events with an estimate,
                steady state (event time >= 0.1 s);
``over2x``      share of those estimates more than 2x off the truth;
``sig``         share of the steady-state signal events with an estimate;
``noise``       share of the noise events given a lifetime (the noise measure;
                NaN without noise);
``noise_floor`` share of the noise events that fired within half a lifetime of
                the passage of an edge of their polarity at their pixel (known
                from the truth of the signal events at the pixel and its 8
                neighbours, see :func:`_signal_distance`): no rule that looks
                at times can tell them from the edge's own events, and a
                method that estimates the edge's events gives these a lifetime
                too; the same for every method, a property of the cell;
``noise_after`` share of the noise events within half a lifetime *after* such a
                passage (part of the floor: they fire while the edge's burst at
                their pixel runs, as its own later events do);
``noise_in_floor``  share of the floor's noise events given a lifetime (``noise_in_after``:
                of those after the passage), and
``noise_off_floor`` share of the other noise events given one: the noise measure
                is ``floor * noise_in_floor + (1 - floor) * noise_off_floor``; a
                method that estimates a share ``c`` of the signal gives the floor's
                events a lifetime at about that rate (they sit in its bursts), so
                its noise measure is at least about ``c * floor`` whatever its rules;
``first``       median |relative error| over the first 0.1 s (start-up, apart).

:func:`run_grid` runs the cells as tasks on the project's Dask glue
(:mod:`evedge.parallel`, as datasets and sweeps do: a task per cell, retries, a
progress bar) or serially (``workers=0``); the rows are the same either way
(each cell depends only on its own scene and seed). The command is
``benchmarks/robustness_grid.py``.
"""

from __future__ import annotations

import itertools
import math
import sys
import time
from dataclasses import dataclass

import numpy as np

THRESHOLD = 0.25  # C+ = C- (log units)
LIGHT = 0.8
LOG_EPS = 1e-3
STEADY_US = 100_000
PERIOD_PX = 20.0
#: Noise events within this many truth lifetimes of a same-pixel, same-polarity signal event count as the floor.
FLOOR_LIFETIMES = 0.5
#: The per-cell figures of :func:`score`, in order.
FIGURES = ("med", "over2x", "sig", "noise", "noise_floor", "noise_after", "noise_in_floor", "noise_in_after",
           "noise_off_floor", "first")


def _dark_for(r: float) -> float:
    """Dark intensity whose log-contrast against LIGHT is ``r`` thresholds."""
    return math.exp(math.log(LIGHT + LOG_EPS) - r * THRESHOLD) - LOG_EPS


def _duration_s(speed: float) -> float:
    # every pixel sees at least about two edge passages, and steady state lasts >= 0.1 s
    return float(min(1.2, max(0.25, 2.5 * PERIOD_PX / speed)))


def _events_table(noise_hz: float) -> dict:
    return {"contrast_pos": THRESHOLD, "contrast_neg": THRESHOLD, "contrast_sigma": 0.02,
            "refractory_us": 100, "noise_rate_hz": float(noise_hz), "log_eps": LOG_EPS}


def stripes_scene(width, height, angle_deg, speed, r, noise_hz, seed) -> dict:
    """Scene dict of a ``stripes`` cell (see the module notes)."""
    a = math.radians(angle_deg)
    return {
        "scene": {"name": f"stripes_{angle_deg}_{speed}", "kind": "stripes", "duration_s": _duration_s(speed),
                  "seed": seed, "frame_rate_hz": 0, "background": LIGHT},
        "sensor": {"width": width, "height": height},
        "events": _events_table(noise_hz),
        "stripes": [{"rows_fraction": [0.0, 1.0], "period_px": PERIOD_PX, "angle_deg": float(angle_deg),
                     "velocity_px_s": [speed * math.cos(a), speed * math.sin(a)], "dark": _dark_for(r),
                     "light": LIGHT, "phase_px": 3.3}],
    }


def rotation_scene(width, height, r, noise_hz, seed, deg_s=120.0) -> dict:
    """Scene dict of a ``rotation`` cell: a dark star rotating about the sensor's centre."""
    rad = 0.42 * min(width, height)
    return {
        "scene": {"name": "rotation", "kind": "shapes", "duration_s": 0.6, "seed": seed, "frame_rate_hz": 0,
                  "background": LIGHT},
        "sensor": {"width": width, "height": height},
        "events": _events_table(noise_hz),
        "motion": {"center_px": [width / 2, height / 2], "angular_velocity_deg_s": deg_s},
        "shapes": [{"kind": "star", "center_px": [width / 2, height / 2], "radius_px": rad, "inner_ratio": 0.45,
                    "intensity": _dark_for(r)}],
    }


def shapes_scene(width, height, speed, r, noise_hz, seed) -> dict:
    """Scene dict of a ``shapes`` cell: triangle, square at 45 degrees and disc translating diagonally."""
    v = speed / math.sqrt(2)
    rad = 0.16 * min(width, height)
    return {
        "scene": {"name": "shapes", "kind": "shapes", "duration_s": _duration_s(speed) * 0.8, "seed": seed,
                  "frame_rate_hz": 0, "background": LIGHT},
        "sensor": {"width": width, "height": height},
        "events": _events_table(noise_hz),
        "motion": {"velocity_px_s": [v, v * 0.6]},
        "shapes": [
            {"kind": "triangle", "center_px": [0.25 * width, 0.3 * height], "radius_px": rad,
             "intensity": _dark_for(r)},
            {"kind": "square", "center_px": [0.6 * width, 0.3 * height], "radius_px": rad, "rotation_deg": 45,
             "intensity": _dark_for(r)},
            {"kind": "circle", "center_px": [0.4 * width, 0.7 * height], "radius_px": rad, "intensity": _dark_for(r)},
        ],
    }


def build(kind: str, width: int, height: int, seed: int, **kw) -> dict:
    """Scene dict of a cell of ``kind`` with the cell's parameters ``kw`` (see :func:`cells`)."""
    if kind == "stripes":
        return stripes_scene(width, height, kw["angle_deg"], kw["speed"], kw["r"], kw["noise_hz"], seed)
    if kind == "rotation":
        return rotation_scene(width, height, kw["r"], kw["noise_hz"], seed)
    if kind == "shapes":
        return shapes_scene(width, height, kw["speed"], kw["r"], kw["noise_hz"], seed)
    raise ValueError(f"unknown cell kind {kind!r} (stripes, rotation, shapes)")


def cells(quick: bool) -> list[tuple[str, dict]]:
    """``(kind, parameters)`` of every cell of the grid (``quick``: the reduced one)."""
    if quick:
        angles, speeds, ratios, noises = (0, 20, 45, 70), (10, 200, 2000), (1.3, 2.2, 5.0), (0.0, 2.0, 5.0)
    else:
        angles, speeds, ratios, noises = (0, 20, 45, 70), (10, 50, 200, 1000, 2000), (1.3, 1.7, 2.2, 3.0, 5.0), \
            (0.0, 0.5, 2.0, 5.0)
    out = []
    # clean: every angle x speed x contrast
    for a, v, r in itertools.product(angles, speeds, ratios):
        out.append(("stripes", dict(angle_deg=a, speed=v, r=r, noise_hz=0.0)))
    # noise: every contrast and noise level at two angles and speeds
    for a, v, r, nz in itertools.product((0, 20) if quick else (0, 20, 45), (10, 200), ratios, noises[1:]):
        out.append(("stripes", dict(angle_deg=a, speed=v, r=r, noise_hz=nz)))
    for r, nz in itertools.product(ratios, (0.0, noises[-1])):
        out.append(("rotation", dict(r=r, noise_hz=nz)))
        out.append(("shapes", dict(speed=100.0, r=r, noise_hz=nz)))
    return out


def _signal_distance(events, truth, *, after_only: bool = False) -> np.ndarray:
    """Per event: time to the edge's passage at its pixel (same polarity), in lifetimes of that edge; ``inf``: none.

    One of :func:`_passage_distances`' two arrays (``after_only``: the second).
    """
    return _passage_distances(events, truth)[1 if after_only else 0]


def _passage_distances(events, truth) -> tuple[np.ndarray, np.ndarray]:
    """Per event, in lifetimes of the edge: the distance to the nearest passage at its pixel, and to the latest one at
    or before it (``inf``: none), from one pass over the signal events.

    The passage is known from every signal event of the same polarity at the
    pixel or one of its 8 neighbours: a signal event at pixel ``s``, time
    ``t_s``, normal flow ``v`` (truth) puts the edge at pixel ``q`` at
    ``t_s + (q - s) . v / |v|^2`` (at ``s`` itself: ``t_s``). The distance is
    ``|t - t_pass| / lifetime_s`` for the passages just before and just after
    ``t`` (a pixel that skipped the passage, low contrast, still saw the edge
    go by); the second array, to the passage at or before ``t`` only (the
    event fired while the edge's burst at its pixel may still run).
    """
    n = events.shape[0]
    nearest = np.full(n, np.inf)
    after = np.full(n, np.inf)
    lt = truth["lifetime_us"]
    sig = truth["is_signal"] & np.isfinite(lt) & (lt > 0)
    if n == 0 or not sig.any():
        return nearest, after
    vx = np.nan_to_num(truth["vx_px_s"][sig]) if "vx_px_s" in truth.dtype.names else np.zeros(sig.sum())
    vy = np.nan_to_num(truth["vy_px_s"][sig]) if "vy_px_s" in truth.dtype.names else np.zeros(sig.sum())
    v2 = vx * vx + vy * vy
    wide = int(events["x"].max()) + 3
    ex = events["x"].astype(np.int64) + 1
    ey = events["y"].astype(np.int64) + 1
    t = events["t"].astype(np.float64)
    keys, times, lts = [], [], []
    for oy in (-1, 0, 1):
        for ox in (-1, 0, 1):
            if ox or oy:
                ok = v2 > 0
                shift = np.where(ok, (ox * vx + oy * vy) / np.where(ok, v2, 1.0) * 1e6, np.nan)
            else:
                shift = np.zeros(v2.size)
            keep = np.isfinite(shift)
            keys.append((((ey[sig] + oy) * wide + ex[sig] + ox) * 2 + events["p"][sig])[keep])
            times.append((t[sig] + shift)[keep])
            lts.append(lt[sig][keep])
    sk, st, sl = np.concatenate(keys), np.concatenate(times), np.concatenate(lts)
    order = np.lexsort((st, sk))
    sk, st, sl = sk[order], st[order], sl[order]
    key = (ey * wide + ex) * 2 + events["p"]
    # (pixel key, time) as one sorted float: times stay within +-5e7 us of 0 (checked), keys are small integers
    if np.abs(st).max() >= 5e7 or np.abs(t).max() >= 5e7:
        raise ValueError("_signal_distance: recordings longer than 50 s are not supported")
    comb = sk * 1e8 + st

    def dist(j):  # to the passage at sorted position j (inf: none there, or another pixel's)
        jj = np.clip(j, 0, sk.size - 1)
        return np.where((j >= 0) & (j < sk.size) & (sk[jj] == key), np.abs(st[jj] - t) / sl[jj], np.inf)

    pos = np.searchsorted(comb, key * 1e8 + t)
    nearest = np.minimum(dist(pos - 1), dist(pos))  # the passages just before and after the event
    after = dist(np.searchsorted(comb, key * 1e8 + t, side="right") - 1)  # the latest at or before it
    return nearest, after


def score(rec, lifetimes) -> dict:
    """The cell's figures for one method's ``lifetimes`` (:data:`FIGURES`, see the module notes).

    Examples
    --------
    >>> from types import SimpleNamespace
    >>> from evedge.detector.result import empty_lifetimes
    >>> from evedge.events import make_events
    >>> ev = make_events([0, 0, 1, 0], [0, 0, 0, 0], [0, 150_000, 150_100, 150_300], [True] * 4)
    >>> truth = np.array([(True, 1000.0), (True, 1000.0), (True, 1000.0), (False, np.nan)],
    ...                  dtype=[("is_signal", bool), ("lifetime_us", float)])
    >>> lt = empty_lifetimes(4)  # the noise event (0.3 lifetimes after a signal event at its pixel) estimated
    >>> lt["valid"], lt["lifetime_us"] = [False, True, False, True], [np.nan, 1500.0, np.nan, 900.0]
    >>> s = score(SimpleNamespace(events=ev, truth=truth), lt)
    >>> s["med"], s["sig"], s["noise"], s["noise_floor"], s["noise_in_floor"], s["noise_off_floor"]
    (0.5, 0.5, 1.0, 1.0, 1.0, nan)
    """
    t = rec.events["t"]
    sig = rec.truth["is_signal"]
    truth = rec.truth["lifetime_us"]
    valid = lifetimes["valid"]
    est = lifetimes["lifetime_us"]
    steady = t >= int(t[0]) + STEADY_US if t.size else np.zeros(0, bool)
    ok = sig & np.isfinite(truth)
    out = {}
    m = ok & steady
    sel = m & valid
    ratio = est[sel] / truth[sel]
    out["med"] = float(np.median(np.abs(ratio - 1))) if ratio.size else math.nan
    out["over2x"] = float(np.mean((ratio > 2) | (ratio < 0.5))) if ratio.size else math.nan
    out["sig"] = float(valid[m].mean()) if m.any() else math.nan
    noise = ~sig
    out["noise"] = float(valid[noise].mean()) if noise.any() else math.nan
    for key in ("noise_floor", "noise_after", "noise_in_floor", "noise_in_after", "noise_off_floor"):
        out[key] = math.nan
    if noise.any():
        in_floor, in_after = (d <= FLOOR_LIFETIMES for d in _passage_distances(rec.events, rec.truth))
        out["noise_floor"] = float(np.mean(in_floor[noise]))
        out["noise_after"] = float(np.mean(in_after[noise]))
        for key, sel in (("noise_in_floor", noise & in_floor), ("noise_in_after", noise & in_after),
                         ("noise_off_floor", noise & ~in_floor)):
            out[key] = float(valid[sel].mean()) if sel.any() else math.nan
    first = ok & ~steady & valid
    r0 = est[first] / truth[first]
    out["first"] = float(np.median(np.abs(r0 - 1))) if r0.size else math.nan
    out["n_signal"] = int(m.sum())
    out["n_noise"] = int(noise.sum())
    return out


@dataclass(frozen=True)
class CellTask:
    """One cell to run (picklable): the scene and the methods, each ``(label, method, params or None)``
    or ``(label, method, params, buffer_params)`` (the noise filter's parameters, e.g. a longer ``tau_min_us``)."""

    kind: str
    params: tuple  # (name, value) pairs of the cell, as cells() gives them
    width: int
    height: int
    seed: int
    methods: tuple


def run_cell(task: CellTask) -> dict:
    """Simulate the cell and score every method on it; one flat row (``<label>_<figure>``, ``<label>_cpu_s``).

    ``cpu_s`` is ``time.process_time`` of the process that ran it: the simulation
    (``sim_cpu_s``) and each method's detection apart.
    """
    from evedge.detector.pipeline import detect
    from evedge.sim import parse_scene, simulate

    kw = dict(task.params)
    c0 = time.process_time()
    rec = simulate(parse_scene(build(task.kind, task.width, task.height, task.seed, **kw), f"<{task.kind}>"),
                   progress=False)
    row = {"kind": task.kind, **{k: kw.get(k, "") for k in ("angle_deg", "speed", "r", "noise_hz")},
           "n_events": int(rec.events.size), "sim_cpu_s": time.process_time() - c0}
    for label, method, params, *buffer in task.methods:
        c1 = time.process_time()
        res = detect(rec.events, rec.sensor_size, method=method, params=params,
                     buffer_params=buffer[0] if buffer else None)
        row[f"{label}_cpu_s"] = time.process_time() - c1
        for k, v in score(rec, res.lifetimes).items():
            row[f"{label}_{k}"] = v
    return row


def tasks(grid, width: int, height: int, seed: int, methods) -> list[CellTask]:
    """The :class:`CellTask` of every ``(kind, parameters)`` of ``grid`` (see :func:`cells`)."""
    return [CellTask(kind, tuple(kw.items()), int(width), int(height), int(seed), tuple(methods)) for kind, kw in grid]


def run_grid(cell_tasks, *, workers: int | None = None, scheduler: str | None = None, client=None,
             progress: bool = True) -> tuple[list[dict], list[tuple[CellTask, BaseException]]]:
    """Run every cell; ``(rows in the order of cell_tasks, failures)``.

    ``workers=0`` runs them in this process, one after the other (a tqdm bar);
    otherwise as tasks on :func:`evedge.parallel.dask_client` (``workers``
    processes of a local cluster, default the cores; or ``scheduler`` / ``client``)
    through :func:`evedge.parallel.run_tasks` (a failing cell is retried, then
    reported in ``failures`` with its error; the others still run). The rows do
    not depend on where a cell ran.
    """
    cell_tasks = list(cell_tasks)
    rows: list = [None] * len(cell_tasks)
    failures = []
    if workers == 0 and client is None and scheduler is None:
        from tqdm import tqdm

        for i, task in enumerate(tqdm(cell_tasks, desc="cells", unit="cell", disable=not progress, file=sys.stderr)):
            try:
                rows[i] = run_cell(task)
            except Exception as err:  # one bad cell does not stop the grid (as on Dask)
                failures.append((task, err))
    else:
        from evedge.parallel import dask_client, run_tasks

        with dask_client(workers, scheduler, client=client) as c:
            for i, result, error in run_tasks(c, run_cell, cell_tasks, progress=progress, desc="cells", unit="cell"):
                if error is not None:
                    failures.append((cell_tasks[i], error))
                else:
                    rows[i] = result
    return [r for r in rows if r is not None], failures
