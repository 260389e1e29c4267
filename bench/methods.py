"""The edge-map methods the experiments compare, behind one function.

``proposed``
    Event buffer (paper section 2.2), lifetimes by plane fitting with
    intra-pixel-area events.
``mueggler``
    Mueggler et al. 2015 lifetimes on the raw events.
``acc_1ms``, ``acc_30ms``
    Pixels with at least one event in ``(T - window, T]`` (the paper's 1 ms and
    30 ms accumulation), raw events.
``acc_count``
    Pixels hit by the last ``n`` events before ``T``. ``n`` is set per
    recording by the caller; the experiments use the mean number of edge
    pixels of the reference maps, i.e. a count that fills about as many pixels
    as the truth has (favourable to this baseline, documented in the report).

Display policies
----------------
A lifetime method's edge map depends on how its lifetimes are displayed (by
how much, next to the estimator's own effect, the report computes per run), so
both lifetime methods are always shown under the *same* policy, and every
experiment runs both:

``predecessor`` (primary; method keys ``proposed``, ``mueggler``)
    Mueggler et al.'s display (``clear_behind=True`` in
    :func:`evedge.detector.edges.edge_frames`): each event keeps its pixel
    alive for its lifetime and clears the 8-neighbour behind it in the motion
    direction. It is primary because the authors' code is a fork of the
    predecessor's MATLAB code (lee-sangil/rpg_event_lifetime) and inherits this
    display (METHOD.md section 4), and it treats both methods alike.
``lifetime_only`` (secondary; keys ``proposed_noclear``, ``mueggler_noclear``)
    The paper's definition alone: a pixel is edge while its newest event is
    alive (``t_e <= T < t_e + tau_e``), nothing cleared.

The accumulation baselines do not depend on the policy. Lifetimes are computed
once per recording and method and reused for every frame and both policies.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Display policy -> ``clear_behind`` of :func:`evedge.detector.edges.edge_frames`.
DISPLAY_CLEAR_BEHIND = {"predecessor": True, "lifetime_only": False}

#: The policies, primary first.
DISPLAYS = tuple(DISPLAY_CLEAR_BEHIND)

#: The policy of the headline comparison, the qualitative panel and the real-frames figure.
PRIMARY_DISPLAY = "predecessor"

#: Why the primary policy is primary (shown in the report and ``results.json``).
PRIMARY_DISPLAY_WHY = (
    "the authors' code is a fork of Mueggler et al.'s MATLAB code (lee-sangil/rpg_event_lifetime) and "
    "inherits its display, which clears the pixel behind each event in the motion direction; shown this way "
    "both lifetime methods get the same display")

#: Human-readable policy names.
DISPLAY_LABELS = {"predecessor": "predecessor display (pixel behind each event cleared)",
                  "lifetime_only": "lifetime-only display (nothing cleared)"}

#: Suffix of a lifetime method's key under each policy (the primary policy keeps the bare key).
_SUFFIX = {"predecessor": "", "lifetime_only": "_noclear"}

#: Lifetime-based methods (their maps depend on the display policy).
LIFETIME_BASES = ("proposed", "mueggler", "mueggler_t0")

#: Accumulation baselines (no display policy).
ACCUMULATION_METHODS = ("acc_1ms", "acc_30ms", "acc_count")


def method_key(base: str, display: str) -> str:
    """Result key of a method under a display policy (``proposed``, ``proposed_noclear``, ``acc_1ms``)."""
    if display not in DISPLAY_CLEAR_BEHIND:
        raise ValueError(f"display must be one of {DISPLAYS}, got {display!r}")
    if base in ACCUMULATION_METHODS:
        return base
    if base not in LIFETIME_BASES:
        raise ValueError(f"method_key: unknown method {base!r}")
    return base + _SUFFIX[display]


def split_key(key: str) -> tuple[str, str | None]:
    """``(base method, display policy)`` of a result key; the policy is None for accumulation."""
    for display, suffix in _SUFFIX.items():
        if suffix and key.endswith(suffix) and key[:-len(suffix)] in LIFETIME_BASES:
            return key[:-len(suffix)], display
    if key in LIFETIME_BASES:
        return key, PRIMARY_DISPLAY
    return key, None


def display_view(per_method: dict, display: str) -> dict:
    """The entries of ``per_method`` (keyed by result key) seen under one policy, keyed by base method.

    Lifetime methods of the other policy are dropped; accumulation baselines
    (and unknown keys) are kept as they are.
    """
    if display not in DISPLAY_CLEAR_BEHIND:
        raise ValueError(f"display must be one of {DISPLAYS}, got {display!r}")
    out = {}
    for key, value in per_method.items():
        base, d = split_key(key)
        if d is None or d == display:
            out[base] = value
    return out


def methods_for(displays=DISPLAYS, bases=("proposed", "mueggler")) -> tuple[str, ...]:
    """Result keys of the lifetime ``bases`` under each of ``displays`` (policy-major order)."""
    return tuple(method_key(b, d) for d in displays for b in bases)


def check_displays(displays, who: str) -> tuple[str, ...]:
    """``displays`` as a tuple; ``ValueError`` naming ``who`` unless a non-empty subset of :data:`DISPLAYS`."""
    displays = tuple(displays)
    bad = [d for d in displays if d not in DISPLAY_CLEAR_BEHIND]
    if bad or not displays:
        raise ValueError(f"{who}: displays must be a non-empty subset of {DISPLAYS}, got {displays!r}")
    return displays


def display_record(displays) -> dict:
    """What was run, for the results: policy -> ``clear_behind``, result keys, label; and the primary policy."""
    return {"primary": PRIMARY_DISPLAY,
            "policies": {d: {"clear_behind": DISPLAY_CLEAR_BEHIND[d], "label": DISPLAY_LABELS[d],
                             "methods": dict(zip(("proposed", "mueggler"), methods_for((d,))))}
                         for d in displays}}


#: The compared methods: both lifetime methods under both policies, then the accumulation baselines.
METHODS = methods_for() + ACCUMULATION_METHODS

#: Extra variants run only to explain results, never ranked in the verdicts.
#: ``mueggler_t0``: Mueggler et al. with its time origin 1 s before the first
#: event; its plane is fitted in absolute time, so its inlier tolerance grows
#: with the time since the origin (see :mod:`evedge.detector.mueggler`). This
#: variant shows how much of its behaviour early in a recording is that quirk
#: (one key per display policy).
DIAGNOSTIC_METHODS = methods_for(bases=("mueggler_t0",))

#: Time origin shift of ``mueggler_t0``.
MUEGGLER_T0_SHIFT_US = 1_000_000

_BASE_LABELS = {
    "proposed": "proposed (intra-pixel-area)",
    "mueggler": "Mueggler et al. 2015",
    "acc_1ms": "1 ms accumulation",
    "acc_30ms": "30 ms accumulation",
    "acc_count": "fixed-count accumulation",
    "mueggler_t0": "Mueggler, time origin 1 s earlier (diagnostic)",
}


def _label(key: str) -> str:
    base, display = split_key(key)
    text = _BASE_LABELS[base]
    if display is not None and display != PRIMARY_DISPLAY:
        text += ", lifetime-only display"
    return text


#: Human-readable method names for figures and the report (the primary policy is unmarked).
METHOD_LABELS = {k: _label(k) for k in METHODS + DIAGNOSTIC_METHODS}


@dataclass
class LifetimeRun:
    """Events a lifetime method used and its per-event lifetimes (aligned)."""

    events: np.ndarray
    lifetimes: np.ndarray
    kept: np.ndarray | None = None  # mask of the input events kept by the buffer


def proposed_lifetimes(events: np.ndarray, sensor_size) -> LifetimeRun:
    """The paper's pipeline (:func:`evedge.detector.pipeline.detect`, method ``intra``):
    event buffer, then intra-pixel-area RANSAC lifetimes on the kept events."""
    from evedge.detector.pipeline import detect

    res = detect(events, sensor_size, method="intra")
    kept = np.asarray(res.kept, dtype=bool)
    return LifetimeRun(events[kept], res.lifetimes[kept], kept)


def mueggler_lifetimes(events: np.ndarray, sensor_size) -> LifetimeRun:
    """Mueggler et al. 2015 lifetimes on the raw events."""
    from evedge.detector.mueggler import estimate_lifetimes_mueggler

    return LifetimeRun(events, estimate_lifetimes_mueggler(events, sensor_size))


def mueggler_t0_lifetimes(events: np.ndarray, sensor_size) -> LifetimeRun:
    """Mueggler et al. 2015 with the time origin :data:`MUEGGLER_T0_SHIFT_US` before the first event."""
    from evedge.detector.mueggler import estimate_lifetimes_mueggler

    t0 = int(events["t"][0]) - MUEGGLER_T0_SHIFT_US if events.size else 0
    return LifetimeRun(events, estimate_lifetimes_mueggler(events, sensor_size, time_origin_us=t0))


_LIFETIME_FUNCS = {"proposed": proposed_lifetimes, "mueggler": mueggler_lifetimes,
                   "mueggler_t0": mueggler_t0_lifetimes}


def edge_maps(events: np.ndarray, sensor_size, times_us, *, methods=METHODS, count_n: int = 2000,
              lifetime_runs: dict | None = None) -> tuple[dict[str, np.ndarray], dict[str, LifetimeRun]]:
    """Edge maps of each method at each time.

    Parameters
    ----------
    events : numpy.ndarray of EVENT_DTYPE
    sensor_size : SensorSize
    times_us : array_like of int
        Query times (microseconds).
    methods : sequence of str
        Subset of :data:`METHODS` + :data:`DIAGNOSTIC_METHODS`; a lifetime
        method's key names its display policy (see :func:`method_key`).
    count_n : int
        Events per map for ``acc_count``.
    lifetime_runs : dict, optional
        Precomputed :class:`LifetimeRun` per lifetime method, keyed by base
        method (``proposed``, ``mueggler``, ``mueggler_t0``); reused, not recomputed.

    Returns
    -------
    maps : dict
        method key -> bool array (n_times, H, W).
    lifetime_runs : dict
        The lifetime runs used, keyed by base method (one per method, shared by
        both display policies).
    """
    from evedge.detector.accumulate import accumulate_count, accumulate_time
    from evedge.detector.edges import edge_frames

    unknown = [m for m in methods if m not in METHODS + DIAGNOSTIC_METHODS]
    if unknown:
        raise ValueError(f"edge_maps: unknown methods {unknown}; choose from {METHODS + DIAGNOSTIC_METHODS}")
    if isinstance(count_n, bool) or int(count_n) < 1:
        raise ValueError(f"edge_maps: count_n must be a positive integer, got {count_n!r}")
    times = np.asarray(times_us, dtype=np.int64)
    runs = dict(lifetime_runs or {})
    maps: dict[str, np.ndarray] = {}
    for m in methods:
        base, display = split_key(m)
        if base in LIFETIME_BASES:
            if base not in runs:
                runs[base] = _LIFETIME_FUNCS[base](events, sensor_size)
            r = runs[base]
            maps[m] = np.asarray(edge_frames(r.events, r.lifetimes, sensor_size, times,
                                             clear_behind=DISPLAY_CLEAR_BEHIND[display]))
        elif m == "acc_1ms":
            maps[m] = np.asarray(accumulate_time(events, sensor_size, times, 1000)) > 0
        elif m == "acc_30ms":
            maps[m] = np.asarray(accumulate_time(events, sensor_size, times, 30_000)) > 0
        else:
            maps[m] = np.asarray(accumulate_count(events, sensor_size, times, int(count_n))) > 0
    return maps, runs
