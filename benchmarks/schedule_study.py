"""RANSAC schedule study: what the trials buy on the estimator's real windows, and what other schedules would cost.

The windows are captured from the project's stream kernel itself (one event per
call of ``_intra_stream``, default :class:`~evedge.detector.intra.IntraParams`;
the scratch arrays then hold the last fit's window points and the cluster RANSAC
ran on). On each captured cluster (``m`` past points plus the current event)
this prints:

* the share of clusters with *full consensus in the model class*: the
  least-squares plane through the current event (``P0``, the RANSAC model) has
  every point as an inlier; RANSAC's maximum is then ``m + 1`` and, when it
  finds it, the refit is the least-squares fit on all points;
* the same with the refit plane ``F`` (free offset) tested through the event;
* today's trials per cluster, the trial where the final best was first found,
  the share hitting ``max_trials`` and the share of full-consensus clusters where
  RANSAC's winner has full consensus too;
* for each schedule, the trials it runs and the share of clusters whose final
  plane equals today's (to 1e-9) or differs by more than 1 % / 10 % in lifetime.

Schedules: ``today`` (the kernel's); ``ls`` (P0 first: full consensus -> no
trial, else today's RANSAC); ``ls+seed`` (P0's consensus is hypothesis 0 of
RANSAC, its count starts the adaptive bound); ``ls+seed+lo`` (also, after every
new best, one least-squares refit through the event on its inliers is scored
as a further hypothesis: LO-RANSAC).

Run: ``.venv/bin/python benchmarks/schedule_study.py [--limit N]``.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
from pathlib import Path

import numpy as np
from numba import njit

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_detector import load_stripes, simulated_shapes  # noqa: E402

from evedge.detector import filter_events  # noqa: E402
from evedge.detector._intra_kernels import (_NEVER, _event_key, _intra_stream, _ls_slopes, off_as_none,  # noqa: E402
                                           scratch_arrays)
from evedge.detector.intra import IntraParams, noise_args  # noqa: E402
from evedge._splitmix import _splitmix64  # noqa: E402

SENT = 99.0


def capture(events, size, pr: IntraParams, limit=None):
    """Per event: (key, m, cluster points (m, 3)) of the last fit RANSAC ran on (m = 0: none)."""
    x, y, t, p = (np.ascontiguousarray(events[c]).astype(np.int64) for c in ("x", "y", "t", "p"))
    n = x.size if limit is None else min(limit, x.size)
    w, h = size.width, size.height
    planes = 2 if pr.per_polarity else 1
    sae = np.full(planes * w * h, _NEVER, np.int64)
    prev_t = np.zeros(sae.size, np.int64)
    prev_lt = np.full(sae.size, np.nan)
    prev_pol = np.full(sae.size, -1, np.int8)
    wf, wi = scratch_arrays(pr.window_size**2)
    lt, vx, vy, valid = np.empty(n), np.empty(n), np.empty(n), np.empty(n, np.bool_)
    keys = np.zeros(n, np.uint64)
    ms = np.zeros(n, np.int64)
    pts = np.zeros((n, pr.window_size**2, 3))
    empty8, empty_f = np.empty(0, np.int8), np.empty(0)
    for k in range(n):
        wf[0, :] = SENT
        idx = np.array([k])
        _intra_stream(x, y, t, p, idx, 0, 0, sae, prev_t, prev_lt, prev_pol, pr.burst_lifetimes, w, h, 0, h, 0, h,
                      empty8, empty_f, pr.per_polarity, pr.window_size // 2, pr.delta_px, pr.inlier_threshold_us,
                      pr.inlier_threshold_rel, pr.max_trials, pr.stop_probability, pr.min_points, pr.min_inliers,
                      pr.refit_intercept, pr.fallback_all_points, pr.seed, off_as_none(pr.split_gap_ratio),
                      off_as_none(pr.event_on_plane), pr.burst_startup, pr.border_px, pr.split_jump_check,
                      pr.stale_fraction, _NEVER, 0.0, noise_args(pr), lt[k:], vx[k:], vy[k:], valid[k:], wf, wi,
                      0.0)
        nn = int(np.argmax(wf[0] == SENT)) if np.any(wf[0] == SENT) else wf.shape[1]
        lab = wi[1, :nn] == 1
        m = int(lab.sum())
        if m < 2 or m + 1 < pr.min_points:
            continue
        keys[k] = _event_key(pr.seed, k)
        ms[k] = m
        pts[k, :m, 0] = wf[0, :nn][lab]
        pts[k, :m, 1] = wf[1, :nn][lab]
        pts[k, :m, 2] = wf[2, :nn][lab]
    return keys, ms, pts


@njit(cache=True)
def _score(P, m, a, b, delta, thr_us, thr_rel):
    slack = delta * (abs(a) + abs(b))
    thr = thr_us + thr_rel * math.sqrt(a * a + b * b)
    cnt = 1
    cost = 0.0
    for q in range(m):
        r = max(abs(P[q, 2] - a * P[q, 0] - b * P[q, 1]) - slack, 0.0)
        if r <= thr:
            cnt += 1
            cost += r
    return cnt, cost


@njit(cache=True)
def _ls(P, m, a, b, delta, thr_us, thr_rel, origin_only, intercept):
    """LS plane on the inliers of (a, b) (all points when origin_only is False and a is NaN)."""
    slack = delta * (abs(a) + abs(b))
    thr = thr_us + thr_rel * math.sqrt(a * a + b * b)
    s1 = 1.0
    sx = sy = st = sxx = sxy = syy = sxt = syt = 0.0
    for q in range(m):
        if math.isnan(a) or max(abs(P[q, 2] - a * P[q, 0] - b * P[q, 1]) - slack, 0.0) <= thr:
            x, y, t = P[q, 0], P[q, 1], P[q, 2]
            s1 += 1.0
            sx += x
            sy += y
            st += t
            sxx += x * x
            sxy += x * y
            syy += y * y
            sxt += x * t
            syt += y * t
    _, a2, b2 = _ls_slopes(s1, sx, sy, st, sxx, sxy, syy, sxt, syt, intercept)  # NaN when singular
    return a2, b2


@njit(cache=True)
def run(keys, ms, pts, mode, delta, thr_us, thr_rel, max_trials, stop_prob, out):
    """out[k] = (trials, first-found trial of the final best, best count, a, b (refit), full P0, full F)."""
    log_fail = math.log(1.0 - stop_prob)
    for k in range(ms.shape[0]):
        m = ms[k]
        out[k, :] = np.nan
        if m == 0:
            continue
        P = pts[k]
        key = keys[k]
        a0, b0 = _ls(P, m, np.nan, np.nan, delta, thr_us, thr_rel, False, False)
        full0 = False
        if math.isfinite(a0):
            full0 = _score(P, m, a0, b0, delta, thr_us, thr_rel)[0] == m + 1
        af, bf = _ls(P, m, np.nan, np.nan, delta, thr_us, thr_rel, False, True)
        fullf = False
        if math.isfinite(af):
            fullf = _score(P, m, af, bf, delta, thr_us, thr_rel)[0] == m + 1
        out[k, 5] = full0
        out[k, 6] = fullf
        best_n = 0
        best_cost = np.inf
        ba = np.nan
        bb = np.nan
        trials = max_trials
        first = 0
        if mode >= 1 and full0:
            a, b = _ls(P, m, np.nan, np.nan, delta, thr_us, thr_rel, False, True)
            out[k, 0] = 0
            out[k, 1] = 0
            out[k, 2] = m + 1
            out[k, 3] = a
            out[k, 4] = b
            continue
        if mode >= 2 and math.isfinite(a0):
            best_n, best_cost = _score(P, m, a0, b0, delta, thr_us, thr_rel)
            ba, bb = a0, b0
            if mode >= 3:
                for _ in range(2):
                    la, lb = _ls(P, m, ba, bb, delta, thr_us, thr_rel, True, False)
                    if not math.isfinite(la):
                        break
                    c, co = _score(P, m, la, lb, delta, thr_us, thr_rel)
                    if c > best_n or (c == best_n and co < best_cost):
                        best_n, best_cost, ba, bb = c, co, la, lb
                    else:
                        break
            w = (best_n - 1) / m
            if w >= 1.0:
                trials = 0
            elif w > 0.0:
                trials = min(trials, math.ceil(log_fail / math.log(1.0 - w * w)))
        kk = 0
        um = np.uint64(m)
        um1 = np.uint64(m - 1)
        while kk < trials:
            pi = np.int64(_splitmix64(key + np.uint64(2 * kk)) % um)
            pj = np.int64(_splitmix64(key + np.uint64(2 * kk + 1)) % um1)
            if pj >= pi:
                pj += 1
            kk += 1
            det = P[pi, 0] * P[pj, 1] - P[pj, 0] * P[pi, 1]
            if det == 0.0:
                continue
            a = (P[pi, 2] * P[pj, 1] - P[pj, 2] * P[pi, 1]) / det
            b = (P[pi, 0] * P[pj, 2] - P[pj, 0] * P[pi, 2]) / det
            c, co = _score(P, m, a, b, delta, thr_us, thr_rel)
            if c > best_n or (c == best_n and co < best_cost):
                best_n, best_cost, ba, bb = c, co, a, b
                first = kk
                if mode >= 3:
                    for _ in range(2):
                        la, lb = _ls(P, m, ba, bb, delta, thr_us, thr_rel, True, False)
                        if not math.isfinite(la):
                            break
                        c2, co2 = _score(P, m, la, lb, delta, thr_us, thr_rel)
                        if c2 > best_n or (c2 == best_n and co2 < best_cost):
                            best_n, best_cost, ba, bb = c2, co2, la, lb
                        else:
                            break
                w = (best_n - 1) / m
                if w >= 1.0:
                    trials = kk
                elif w > 0.0:
                    trials = min(trials, math.ceil(log_fail / math.log(1.0 - w * w)))
        out[k, 0] = kk
        out[k, 1] = first
        out[k, 2] = best_n
        if best_n > 0:
            a, b = _ls(P, m, ba, bb, delta, thr_us, thr_rel, False, True)
            out[k, 3] = a
            out[k, 4] = b


def study(name, events, size, limit):
    pr = IntraParams()
    keys, ms, pts = capture(events, size, pr, limit)
    sel = ms > 0
    print(f"\n{name}: {ms.size} kept events, {sel.sum()} clusters RANSAC ran on, mean m = {ms[sel].mean():.1f}")
    outs = {}
    for mode, label in enumerate(("today", "ls", "ls+seed", "ls+seed+lo")):
        out = np.empty((ms.size, 7))
        run(keys, ms, pts, mode, pr.delta_px, pr.inlier_threshold_us, pr.inlier_threshold_rel, pr.max_trials,
            pr.stop_probability, out)
        outs[label] = out[sel]
    base = outs["today"]
    full0 = base[:, 5] == 1
    fullf = base[:, 6] == 1
    full_r = base[:, 2] == ms[sel] + 1
    print(f"  full consensus of P0 (LS through the event): {full0.mean():.3f}; of F (free offset): {fullf.mean():.3f};"
          f" either {(full0 | fullf).mean():.3f}")
    print(f"  today: trials {base[:, 0].mean():.2f} per cluster, final best first found at trial {base[:, 1].mean():.2f},"
          f" cap hit {np.mean(base[:, 0] >= pr.max_trials):.3f}; RANSAC's winner has full consensus "
          f"{full_r.mean():.3f} (in P0-full clusters {full_r[full0].mean():.3f});"
          f" trials in P0-full clusters {base[full0, 0].mean():.2f}, in the others {base[~full0, 0].mean():.2f}")
    lt0 = np.hypot(base[:, 3], base[:, 4])
    for label, o in outs.items():
        lt = np.hypot(o[:, 3], o[:, 4])
        both = np.isfinite(lt) & np.isfinite(lt0)
        rel = np.abs(lt[both] / lt0[both] - 1)
        print(f"  {label:12s} trials {o[:, 0].mean():5.2f}  (no trial {np.mean(o[:, 0] == 0):.3f}, cap "
              f"{np.mean(o[:, 0] >= pr.max_trials):.3f})  same plane {np.mean(rel < 1e-9):.3f}  >1% off "
              f"{np.mean(rel > 0.01):.3f}  >10% off {np.mean(rel > 0.1):.3f}  best count {np.nanmean(o[:, 2]):.2f}")


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--limit", type=int, default=None, help="first N kept events per sequence")
    a = ap.parse_args(argv)
    print(f"load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} CPUs")
    for name, seq in (("stripes.mat", load_stripes()), ("shapes_translation (sim, 2 s)", simulated_shapes())):
        if seq is None:
            continue
        ev, size = seq
        sub = ev[filter_events(ev, size)]
        study(name, sub, size, a.limit)
    print(f"load average {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
