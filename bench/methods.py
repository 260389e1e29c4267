"""The edge-map methods the experiments compare: registered methods under a display policy.

Every compared method is a registered method of
:data:`evedge.detector.protocols.METHODS` with fixed parameters and, for a
lifetime estimator, a display policy (:data:`evedge.detector.edges.DISPLAYS`).
:data:`COMPARED` lists them under their *result keys* (the keys of the
experiments' tables); a key is looked up, never parsed (:func:`compared`).

``proposed`` (registry ``intra``)
    Event buffer (paper section 2.2), lifetimes by plane fitting with
    intra-pixel-area events.
``mueggler`` (registry ``mueggler``)
    Mueggler et al. 2015 lifetimes on the raw events.
``acc_1ms``, ``acc_30ms`` (registry ``time``)
    Pixels with at least one event in ``(T - window, T]`` (the paper's 1 ms and
    30 ms accumulation), raw events.
``acc_count`` (registry ``count``)
    Pixels hit by the last ``n`` events before ``T``. ``n`` is set per
    recording by the caller; the experiments use the mean number of edge
    pixels of the reference maps, i.e. a count that fills about as many pixels
    as the truth has (favourable to this baseline, documented in the report).

Any other registered estimator or edge detector (a plug-in, or
``package.module:factory``) joins through :func:`add_method`; it is compared
beside the built-ins but never ranked by the paper's verdicts.

Display policies
----------------
A lifetime method's edge map depends on how its lifetimes are displayed, so
both lifetime methods are always shown under the *same* policy, and every
experiment runs both:

``predecessor`` (primary; keys ``proposed``, ``mueggler``)
    Mueggler et al.'s display (``clear_behind=True``): each event keeps its
    pixel alive for its lifetime and clears the 8-neighbour behind it in the
    motion direction. It is primary because the authors' code is a fork of the
    predecessor's MATLAB code (lee-sangil/rpg_event_lifetime) and inherits this
    display (METHOD.md section 4), and it treats both methods alike.
``lifetime_only`` (secondary; keys ``proposed_noclear``, ``mueggler_noclear``)
    The paper's definition alone: a pixel is edge while its newest event is
    alive (``t_e <= T < t_e + tau_e``), nothing cleared; burst-aware (issue 11):
    an event that continues its pixel's burst is alive from the burst's first
    event (:data:`evedge.detector.edges.DISPLAY_BURST_LIFETIMES`).

The accumulation baselines do not depend on the policy. Lifetimes are computed
once per recording and method and reused for every frame and both policies.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from evedge.detector.edges import DISPLAYS as _DISPLAY_POLICIES
from evedge.detector.edges import PRIMARY_DISPLAY
from evedge.detector.protocols import METHODS as REGISTRY

#: Display policy -> ``clear_behind`` of :func:`evedge.detector.edges.edge_frames`.
DISPLAY_CLEAR_BEHIND = dict(_DISPLAY_POLICIES)

#: The policies, primary first.
DISPLAYS = tuple(sorted(DISPLAY_CLEAR_BEHIND, key=lambda d: d != PRIMARY_DISPLAY))

#: Why the primary policy is primary (shown in the report and ``results.json``).
PRIMARY_DISPLAY_WHY = (
    "the authors' code is a fork of Mueggler et al.'s MATLAB code (lee-sangil/rpg_event_lifetime) and "
    "inherits its display, which clears the pixel behind each event in the motion direction; shown this way "
    "both lifetime methods get the same display")

#: Human-readable policy names.
DISPLAY_LABELS = {"predecessor": "predecessor display (pixel behind each event cleared)",
                  "lifetime_only": "lifetime-only display (nothing cleared; a burst lives from its first event)"}

#: Time origin shift of ``mueggler_t0``.
MUEGGLER_T0_SHIFT_US = 1_000_000


@dataclass(frozen=True)
class Compared:
    """One compared method: a registered method, its fixed parameters and its display policy.

    Attributes
    ----------
    key : str
        Result key (tables, ``results.json``).
    base : str
        The key shared by its display policies (``proposed`` for ``proposed_noclear``).
    method : str
        Registry name (``intra``, ``time``, a plug-in's name or ``module:factory``).
    display : str or None
        Display policy of a lifetime estimator; None for an edge detector.
    params : dict
        Fixed parameters of the registered factory.
    label : str
        For legends and tables (the registry's display name, plus the variant).
    colour : str
    diagnostic : bool
        Run only to explain results (never ranked).
    builtin : bool
        One of the paper's methods (the verdicts rank only these).
    time_origin_shift_us : int or None
        Mueggler's time origin this far before the first event (the diagnostic variant).
    """

    key: str
    base: str
    method: str
    display: str | None
    params: dict = field(default_factory=dict)
    label: str = ""
    colour: str = "k"
    diagnostic: bool = False
    builtin: bool = True
    time_origin_shift_us: int | None = None


#: Result key of each compared method, in table order.
COMPARED: dict[str, Compared] = {}


def _key(base: str, display: str | None) -> str:
    # the primary policy keeps the bare key; the other gets its own key (a name, looked up, never parsed)
    return base if display in (None, PRIMARY_DISPLAY) else f"{base}_noclear"


def _add_lifetime(base: str, method: str, *, label: str | None = None, diagnostic=False, builtin=True,
                  shift=None, params=None) -> None:
    entry = REGISTRY.get(method, kind="estimator")
    for d in DISPLAYS:
        text = label or entry.display_name
        if d != PRIMARY_DISPLAY:
            text += ", lifetime-only display"
        key = _key(base, d)
        COMPARED[key] = Compared(key, base, method, d, dict(params or {}), text, entry.colour, diagnostic, builtin,
                                 shift)


def _add_edges(key: str, method: str, params: dict, *, label: str | None = None, colour: str | None = None,
               builtin=True) -> None:
    entry = REGISTRY.get(method, kind="edges")
    COMPARED[key] = Compared(key, key, method, None, dict(params), label or entry.display_name,
                             colour or entry.colour, False, builtin)


_add_lifetime("proposed", "intra")
_add_lifetime("mueggler", "mueggler")
_add_edges("acc_1ms", "time", {"window_us": 1000}, label="1 ms accumulation")
_add_edges("acc_30ms", "time", {"window_us": 30_000}, label="30 ms accumulation", colour="#17becf")
_add_edges("acc_count", "count", {}, label="fixed-count accumulation")  # n_events set per recording
_add_lifetime("mueggler_t0", "mueggler", label="Mueggler, time origin 1 s earlier (diagnostic)", diagnostic=True,
              shift=MUEGGLER_T0_SHIFT_US)

#: Lifetime-based methods (their maps depend on the display policy), by base key.
LIFETIME_BASES = ("proposed", "mueggler", "mueggler_t0")

#: Accumulation baselines (no display policy).
ACCUMULATION_METHODS = ("acc_1ms", "acc_30ms", "acc_count")


def add_method(name: str) -> tuple[str, ...]:
    """Compare the registered method ``name`` (or ``package.module:factory``) too; its result keys.

    An estimator gets one key per display policy (``name`` under the primary
    one), an edge detector one key; the registry's display name labels them.
    Calling it again for the same name returns the same keys.
    """
    if name in COMPARED and not COMPARED[name].builtin:
        return tuple(k for k, c in COMPARED.items() if c.base == name)
    if name in COMPARED or name in REGISTRY and any(c.method == name for c in COMPARED.values()):
        raise ValueError(f"method {name!r} is already one of the compared built-ins")
    entry = REGISTRY.get(name, kind=("estimator", "edges"))
    if entry.kind == "estimator":
        _add_lifetime(name, name, builtin=False)
    else:
        _add_edges(name, name, {}, builtin=False)
    return tuple(k for k, c in COMPARED.items() if c.base == name)


def compared(key: str) -> Compared:
    """The :class:`Compared` of a result key; ``ValueError`` naming the known keys otherwise."""
    try:
        return COMPARED[key]
    except KeyError:
        raise ValueError(f"unknown compared method {key!r}; known: {', '.join(COMPARED)}") from None


def _registered(key: str):
    """The registry entry of a method name or ``module:factory`` (None when it resolves to nothing)."""
    try:
        return REGISTRY.get(key)
    except ValueError:  # RegistryError: not registered, not importable (e.g. graded from a file only)
        return None


def label(key: str) -> str:
    """Legend / table label of a result key or method name (the key itself when nothing is known of it)."""
    c = COMPARED.get(key)
    if c is not None:
        return c.label
    entry = _registered(key)
    return entry.display_name if entry is not None else key


def colour(key: str, default: str = "k") -> str:
    """Figure colour of a result key (or of a registered method's name)."""
    c = COMPARED.get(key)
    if c is not None:
        return c.colour
    entry = _registered(key)
    return entry.colour if entry is not None else default


def method_key(base: str, display: str) -> str:
    """Result key of a method under a display policy (``proposed``, ``proposed_noclear``, ``acc_1ms``)."""
    if display not in DISPLAY_CLEAR_BEHIND:
        raise ValueError(f"display must be one of {DISPLAYS}, got {display!r}")
    for c in COMPARED.values():
        if c.base == base and c.display in (None, display):
            return c.key
    raise ValueError(f"method_key: unknown method {base!r}")


def display_view(per_method: dict, display: str) -> dict:
    """The entries of ``per_method`` (keyed by result key) seen under one policy, keyed by base method.

    Lifetime methods of the other policy are dropped; accumulation baselines
    (and unknown keys) are kept as they are.
    """
    if display not in DISPLAY_CLEAR_BEHIND:
        raise ValueError(f"display must be one of {DISPLAYS}, got {display!r}")
    out = {}
    for key, value in per_method.items():
        c = COMPARED.get(key)
        if c is None or c.display is None or c.display == display:
            out[c.base if c else key] = value
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

#: Human-readable method names of the built-ins (see :func:`label` for any key).
METHOD_LABELS = {k: c.label for k, c in COMPARED.items()}


@dataclass
class LifetimeRun:
    """Events a lifetime method used and its per-event lifetimes (aligned)."""

    events: np.ndarray
    lifetimes: np.ndarray
    kept: np.ndarray | None = None  # mask of the input events kept by the filter


def lifetime_run(base: str, events: np.ndarray, sensor_size) -> LifetimeRun:
    """Lifetimes of the compared lifetime method ``base`` (its registered filter, then its estimator).

    The filter is the one the method is registered with (the proposed method:
    the event buffer, as the paper; Mueggler: none, as its original).
    """
    from evedge.detector.pipeline import detect

    c = compared(base)
    if c.display is None:
        raise ValueError(f"{base!r} is not a lifetime method")
    params = dict(c.params)
    if c.time_origin_shift_us is not None:
        params["time_origin_us"] = int(events["t"][0]) - c.time_origin_shift_us if events.size else 0
    res = detect(events, sensor_size, method=c.method, params=params or None)
    kept = np.asarray(res.kept, dtype=bool)
    if kept.all():
        return LifetimeRun(events, res.lifetimes)
    return LifetimeRun(events[kept], res.lifetimes[kept], kept)


def proposed_lifetimes(events: np.ndarray, sensor_size) -> LifetimeRun:
    """The paper's pipeline (registry ``intra``): event buffer, then intra-pixel-area RANSAC on the kept events."""
    run = lifetime_run("proposed", events, sensor_size)
    if run.kept is None:
        run.kept = np.ones(events.shape[0], bool)
    return run


def mueggler_lifetimes(events: np.ndarray, sensor_size) -> LifetimeRun:
    """Mueggler et al. 2015 lifetimes on the raw events."""
    return lifetime_run("mueggler", events, sensor_size)


def mueggler_t0_lifetimes(events: np.ndarray, sensor_size) -> LifetimeRun:
    """Mueggler et al. 2015 with the time origin :data:`MUEGGLER_T0_SHIFT_US` before the first event."""
    return lifetime_run("mueggler_t0", events, sensor_size)


def edge_detector_frames(method: str, events: np.ndarray, sensor_size, times_us, params=None) -> np.ndarray:
    """bool (n_times, H, W) maps of a registered edge detector (:func:`evedge.detector.pipeline.edge_frames_of`)."""
    from evedge.detector.pipeline import edge_frames_of

    return edge_frames_of(method, events, sensor_size, times_us, params)


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
        Result keys of :data:`COMPARED` (see :func:`add_method` for plug-ins).
    count_n : int
        Events per map for ``acc_count``.
    lifetime_runs : dict, optional
        Precomputed :class:`LifetimeRun` per lifetime method, keyed by base
        key (``proposed``, ``mueggler``, ``mueggler_t0``); reused, not recomputed.

    Returns
    -------
    maps : dict
        method key -> bool array (n_times, H, W).
    lifetime_runs : dict
        The lifetime runs used, keyed by base key (one per method, shared by
        both display policies).
    """
    from evedge.detector.edges import edge_frames

    unknown = [m for m in methods if m not in COMPARED]
    if unknown:
        raise ValueError(f"edge_maps: unknown methods {unknown}; choose from {tuple(COMPARED)}")
    if isinstance(count_n, bool) or int(count_n) < 1:
        raise ValueError(f"edge_maps: count_n must be a positive integer, got {count_n!r}")
    times = np.asarray(times_us, dtype=np.int64)
    runs = dict(lifetime_runs or {})
    maps: dict[str, np.ndarray] = {}
    for m in methods:
        c = COMPARED[m]
        if c.display is not None:
            if c.base not in runs:
                runs[c.base] = lifetime_run(c.base, events, sensor_size)
            r = runs[c.base]
            maps[m] = np.asarray(edge_frames(r.events, r.lifetimes, sensor_size, times, display=c.display))
        else:
            params = dict(c.params)
            if c.key == "acc_count":
                params["n_events"] = int(count_n)
            maps[m] = edge_detector_frames(c.method, events, sensor_size, times, params)
    return maps, runs
