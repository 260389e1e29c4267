"""Dataset specs: many varied sequences from one TOML file, each reproducible on its own.

A spec (schema in ``sim/DATASETS.md``) names a scene family and, per
parameter, a fixed value or a distribution (``uniform``, ``log_uniform``,
``integers``, ``choice``), and how many sequences to make. Sequence ``i`` is a
plain scene dict (validated by :func:`evedge.sim.parse_scene`) whose
parameters and simulator seed derive only from ``(spec seed, i)``:

* every parameter has its own random stream,
  ``SeedSequence(seed, spawn_key=(i, crc32(name)[, k]))`` (``k``: the shape
  index for per-shape parameters), so adding a parameter to a spec, or
  drawing in another order, never changes the other draws;
* the scene's seed (threshold mismatch, noise, jitter) is drawn from
  ``SeedSequence(seed, spawn_key=(i, 0))``.

So the same spec gives the same scene, hence the same bytes, for sequence
``i`` whichever worker makes it and whenever. Streams are numpy's
``SeedSequence`` (hashing of the key, independent streams by construction)
rather than :mod:`evedge._splitmix`, which keys draws inside numba kernels.

Validation reuses the scene loader's key-by-key reader, so a bad key is named
the same way: ``spec.toml: key 'parameters.speed_px_s.log_uniform': ...``.
"""

from __future__ import annotations

import math
import zlib
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from .scene import MAX_DURATION_S, SENSOR_PRESETS, SHAPE_KINDS, SceneError, _read_toml, _Table, parse_scene

#: Scene families a dataset can draw from: the planar scene kinds, and boxes (a ``mesh`` scene).
FAMILIES = ("stripes", "shapes", "boxes")
#: Distributions a parameter may take instead of a fixed value.
DISTRIBUTIONS = ("uniform", "log_uniform", "integers", "choice")
#: Largest number of sequences in one spec.
MAX_COUNT = 10_000_000
#: Shape kinds a dataset draws from (regular ones: a polygon needs explicit vertices).
DATASET_SHAPE_KINDS = tuple(k for k in SHAPE_KINDS if k != "polygon")
#: spawn_key slot of the scene seed (parameter streams use crc32 of their name, never 0 for real names).
_SCENE_SEED_SLOT = 0


class DatasetError(SceneError):
    """A dataset spec is invalid; the message names file, key and problem (like :class:`SceneError`)."""


@dataclass(frozen=True)
class Param:
    """One spec parameter: its type, bounds (as the scene loader checks them), default and meaning."""

    kind: str  # "number", "integer" or "string"
    default: Any
    doc: str
    lo: float | None = None
    hi: float | None = None
    lo_open: bool = False
    choices: tuple | None = None
    per_shape: bool = False
    families: tuple[str, ...] | None = None  # the families it applies to (None: all)


def _sensor_name(v: str) -> str | None:
    """None when ``v`` is a preset or ``WxH``; else the problem."""
    if v in SENSOR_PRESETS:
        return None
    w, sep, h = v.partition("x")
    if sep and w.isdigit() and h.isdigit() and 1 <= int(w) <= 32767 and 1 <= int(h) <= 32767:
        return None
    return f"must be a preset {sorted(SENSOR_PRESETS)} or 'WIDTHxHEIGHT' (e.g. '64x48'), got {v!r}"


#: Every parameter a spec may set, in the order they are documented (``sim/DATASETS.md``).
PARAMETERS: dict[str, Param] = {
    "family": Param("string", "stripes", "scene family", choices=FAMILIES),
    "sensor": Param("string", "dvs128", "sensor preset or 'WxH'"),
    "duration_s": Param("number", 0.2, "simulated time per sequence", lo=0, lo_open=True, hi=MAX_DURATION_S),
    "frame_rate_hz": Param("number", 100.0, "rate of clean frames and exact edge maps (0: none)", lo=0, hi=1e6),
    "speed_px_s": Param("number", 100.0, "image speed of the pattern", lo=0),
    "direction_deg": Param("number", 0.0, "direction of motion (0: +x, 90: +y, image axes)"),
    "angle_deg": Param("number", 0.0, "stripes: direction of the stripe normal; shapes: rotation at t = 0; "
                                      "boxes: camera roll at t = 0"),
    "angular_velocity_deg_s": Param("number", 0.0, "shapes: rotation speed about the image centre; "
                                                   "boxes: camera roll rate", families=("shapes", "boxes")),
    "contrast": Param("number", 0.6, "Michelson contrast of pattern against background", lo=0, lo_open=True, hi=1),
    "mean_intensity": Param("number", 0.5, "mean of dark and light (linear)", lo=0, lo_open=True, hi=1),
    "period_px": Param("number", 20.0, "stripes: period", lo=0, lo_open=True, families=("stripes",)),
    "shape_count": Param("integer", 3, "shapes: number of shapes (laid out on a grid)", lo=1, hi=1024,
                         families=("shapes",)),
    "shape_kind": Param("string", "square", "shapes: kind of each shape (drawn per shape)",
                        choices=DATASET_SHAPE_KINDS, per_shape=True),
    "shape_radius_px": Param("number", 10.0, "shapes: circumradius of each shape (drawn per shape)",
                             lo=0, lo_open=True, per_shape=True),
    "box_count": Param("integer", 3, "boxes: number of boxes (laid out on a grid of the image)", lo=1, hi=256,
                       families=("boxes",)),
    "box_depth_m": Param("number", 3.0, "boxes: depth of each box centre (drawn per box)", lo=0.2, hi=1e4,
                         per_shape=True),
    "box_size_m": Param("number", 0.6, "boxes: edge of each (cubic) box (drawn per box)", lo=0, lo_open=True,
                        per_shape=True),
    "threshold": Param("number", 0.2, "contrast threshold C+ = C- (log units)", lo=0, lo_open=True),
    "threshold_mismatch": Param("number", 0.0, "per-pixel threshold std (events.contrast_sigma)", lo=0),
    "noise_rate_hz": Param("number", 0.0, "background activity per pixel", lo=0, hi=1e6),
    "refractory_us": Param("number", 0.0, "refractory period", lo=0),
    "jitter_us": Param("number", 0.0, "half-normal latency scale of signal events", lo=0, hi=1e12),
}


@dataclass(frozen=True)
class Distribution:
    """A parameter's value: ``fixed`` (``args = (value,)``) or one of :data:`DISTRIBUTIONS`."""

    kind: str
    args: tuple

    @property
    def varies(self) -> bool:
        if self.kind == "fixed":
            return False
        if self.kind == "choice":
            return len(set(self.args)) > 1
        return self.args[0] != self.args[1]

    def draw(self, rng: np.random.Generator):
        if self.kind == "fixed":
            return self.args[0]
        if self.kind == "choice":
            return self.args[int(rng.integers(len(self.args)))]
        lo, hi = self.args
        if self.kind == "integers":
            return int(rng.integers(lo, hi + 1))
        if self.kind == "uniform":
            return float(lo + (hi - lo) * rng.random())
        return float(math.exp(math.log(lo) + (math.log(hi) - math.log(lo)) * rng.random()))

    def describe(self) -> str:
        if self.kind == "fixed":
            return repr(self.args[0])
        if self.kind == "choice":
            return f"choice {list(self.args)}"
        return f"{self.kind} [{self.args[0]}, {self.args[1]}]"


@dataclass(frozen=True)
class DatasetSpec:
    """A validated dataset spec. ``raw`` is the parsed TOML; ``source`` the name used in messages."""

    name: str
    seed: int
    count: int
    parameters: dict[str, Distribution]
    description: str = ""
    source: str = "<dataset>"
    raw: dict = field(default_factory=dict, compare=False, repr=False)
    text: str = field(default="", compare=False, repr=False)  # the spec file's text, for the dataset card

    @property
    def swept(self) -> tuple[str, ...]:
        """Parameters that vary across sequences, in :data:`PARAMETERS` order."""
        return tuple(k for k in PARAMETERS if self.parameters[k].varies)

    def sequence_name(self, index: int) -> str:
        """``seq_00042``: zero-padded to at least 5 digits, enough for ``count``."""
        return f"seq_{index:0{max(5, len(str(self.count - 1)))}d}"

    def sequence(self, index: int) -> "Sequence":
        """Parameters, seed and scene dict of sequence ``index`` (see the module docstring)."""
        return make_sequence(self, index)


@dataclass(frozen=True)
class Sequence:
    """One sequence of a dataset: drawn parameters (JSON-able), the scene seed and the scene dict."""

    index: int
    name: str
    params: dict
    seed: int
    scene: dict


def _value(t: _Table, name: str, p: Param):
    """Read key ``name`` of ``t`` as one value of parameter ``p`` (the scene loader's checks)."""
    if p.kind == "string":
        v = t.string(name, choices=p.choices)
        if p is PARAMETERS["sensor"]:
            problem = _sensor_name(v)
            if problem:
                t.fail(name, problem)
        return v
    return t.number(name, lo=p.lo, hi=p.hi, lo_open=p.lo_open, integer=p.kind == "integer")


def _distribution(params: _Table, name: str, p: Param) -> Distribution:
    raw = params.raw(name)
    if not isinstance(raw, dict):
        return Distribution("fixed", (_value(params, name, p),))
    if not raw:
        params.fail(name, f"an empty table; give a value or one of {list(DISTRIBUTIONS)}")
    t = _Table(params.source, params.key(name), raw)
    given = [k for k in raw if k in DISTRIBUTIONS]
    if len(given) != 1:
        t.fail(given[1] if given else next(iter(raw)),
               f"give exactly one of {list(DISTRIBUTIONS)}" if given else
               f"unknown distribution (allowed: {list(DISTRIBUTIONS)})")
    kind = given[0]
    v = t.raw(kind)
    t.finish()
    if kind == "choice":
        if not isinstance(v, list) or not v:
            t.fail(kind, f"expected a non-empty array of values, got {v!r}")
        # an empty prefix makes the item's key the full path: 'parameters.x.choice[2]'
        items = _Table(t.source, "", {f"{t.key(kind)}[{j}]": a for j, a in enumerate(v)})
        values = tuple(_value(items, f"{t.key(kind)}[{j}]", p) for j in range(len(v)))
        return Distribution("choice", values)
    if p.kind == "string":
        t.fail(kind, f"a text parameter takes a fixed value or 'choice', not {kind!r}")
    if kind == "integers" and p.kind != "integer":
        t.fail(kind, "'integers' is for integer parameters; use 'uniform' or 'log_uniform'")
    if kind != "integers" and p.kind == "integer":
        t.fail(kind, f"an integer parameter takes 'integers' or 'choice', not {kind!r}")
    if not isinstance(v, list) or len(v) != 2:
        t.fail(kind, f"expected [low, high], got {v!r}")
    ends = _Table(t.source, "", {f"{t.key(kind)}[{j}]": v[j] for j in (0, 1)})
    lo, hi = (_value(ends, f"{t.key(kind)}[{j}]", p) for j in (0, 1))
    if hi < lo:
        t.fail(kind, f"needs low <= high, got {v!r}")
    if kind == "log_uniform" and lo <= 0:
        t.fail(kind, f"needs low > 0 (log scale), got {v!r}")
    return Distribution(kind, (lo, hi))


def parse_dataset(data: dict, source: str = "<dataset>") -> DatasetSpec:
    """Validate a dataset spec dict (the parsed TOML) and return a :class:`DatasetSpec`.

    Parameters
    ----------
    data : dict
        The spec, as :func:`tomllib.loads` gives it (schema in ``sim/DATASETS.md``).
    source : str
        The file name quoted in messages (and the default dataset name's stem).

    Returns
    -------
    DatasetSpec

    Raises
    ------
    DatasetError
        With a message naming ``source``, the key and the problem.

    Examples
    --------
    >>> spec = parse_dataset({"dataset": {"count": 3, "seed": 1},
    ...                       "parameters": {"speed_px_s": {"log_uniform": [30, 300]}}}, "mine.toml")
    >>> spec.name, spec.count, spec.swept
    ('mine', 3, ('speed_px_s',))
    >>> spec.sequence(2) == spec.sequence(2)
    True
    """
    try:
        top = _Table(source, "", data)
        head = top.table("dataset", required=True)
        name = head.string("name", Path(source).stem)
        seed = head.number("seed", 0, lo=0, hi=2**63 - 1, integer=True)
        count = head.number("count", lo=1, hi=MAX_COUNT, integer=True)
        description = head.string("description", "")
        head.finish()
        params = top.table("parameters")
        dists = {k: (_distribution(params, k, p) if params.has(k) else Distribution("fixed", (p.default,)))
                 for k, p in PARAMETERS.items()}
        params.used.update(PARAMETERS)  # so an unknown key's message lists them all
        params.finish()
        top.finish()
    except SceneError as err:
        raise DatasetError(str(err)) from None
    return DatasetSpec(name=name, seed=seed, count=count, parameters=dists, description=description,
                       source=source, raw=data)


def shipped_datasets() -> tuple[str, ...]:
    """Names of the dataset specs shipped with evedge (``scenes/datasets/*.toml``, package data)."""
    from importlib.resources import files

    folder = files("evedge.scenes") / "datasets"
    return tuple(sorted(p.name[:-5] for p in folder.iterdir() if p.name.endswith(".toml")))


def dataset_path(spec) -> Path:
    """``spec`` itself when it is a file, else the shipped spec of that name (``small``).

    Raises
    ------
    DatasetError
        Neither a file nor a shipped name (the shipped names are listed).
    """
    from importlib.resources import files

    path = Path(spec)
    if path.is_file() or path.suffix or len(path.parts) > 1:
        return path  # a path: load_dataset names it if it cannot be read
    shipped = shipped_datasets()
    if str(spec) in shipped:
        return Path(str(files("evedge.scenes") / "datasets" / f"{spec}.toml"))
    raise DatasetError(f"{spec}: no such file, and no shipped dataset spec of that name (shipped: "
                       f"{', '.join(shipped)})")


def load_dataset(path) -> DatasetSpec:
    """Read and validate a dataset spec file (TOML, schema in ``sim/DATASETS.md``).

    Parameters
    ----------
    path : path-like

    Returns
    -------
    DatasetSpec

    Raises
    ------
    DatasetError
        Unreadable file, invalid TOML or UTF-8, or any invalid key (named).
    """
    path = Path(path)
    text, data = _read_toml(path, "dataset spec", DatasetError)
    return replace(parse_dataset(data, source=str(path)), text=text)


def _stream(spec: DatasetSpec, index: int, *key: int) -> np.random.Generator:
    return np.random.default_rng(np.random.SeedSequence(spec.seed, spawn_key=(index, *key)))


def _crc(name: str) -> int:
    return zlib.crc32(name.encode()) or 1  # slot 0 is the scene seed's


def draw_parameters(spec: DatasetSpec, index: int) -> dict:
    """The parameter values of sequence ``index``.

    Per-shape (per-box) ones are lists of ``shape_count`` (``box_count``)
    values, empty for other families; a parameter that does not apply to the
    drawn family (``period_px`` of a shapes sequence) is None. Its stream is
    still its own, so the others do not depend on it.
    """
    if isinstance(index, bool) or not isinstance(index, (int, np.integer)) or not 0 <= index < spec.count:
        raise ValueError(f"{spec.source}: sequence index must be an integer in [0, {spec.count}), got {index!r}")
    index = int(index)
    out = {}
    for name, p in PARAMETERS.items():
        if not p.per_shape:
            out[name] = spec.parameters[name].draw(_stream(spec, index, _crc(name)))
    for name, p in PARAMETERS.items():
        if p.families is not None and out["family"] not in p.families:
            out[name] = None
    counts = {"shape": out["shape_count"] if out["family"] == "shapes" else 0,
              "box": out["box_count"] if out["family"] == "boxes" else 0}
    for name, p in PARAMETERS.items():
        if p.per_shape:
            n = counts[name.split("_")[0]]
            out[name] = [spec.parameters[name].draw(_stream(spec, index, _crc(name), k)) for k in range(n)]
    return out


def _sensor_table(name: str) -> dict:
    if name in SENSOR_PRESETS:
        return {"preset": name}
    w, _, h = name.partition("x")
    return {"width": int(w), "height": int(h)}


def _sensor_size(name: str) -> tuple[int, int]:
    s = SENSOR_PRESETS.get(name)
    if s is not None:
        return s["width"], s["height"]
    w, _, h = name.partition("x")
    return int(w), int(h)


def _intrinsics(name: str) -> tuple[float, float, float, float]:
    """(fx, fy, cx, cy) the scene loader gives this sensor (``WxH``: f = width, centred)."""
    s = SENSOR_PRESETS.get(name)
    if s is not None:
        return s["fx"], s["fy"], s["cx"], s["cy"]
    w, h = _sensor_size(name)
    return float(w), float(w), (w - 1) / 2, (h - 1) / 2


def _grid(n: int, w: int, h: int) -> tuple[int, float, float]:
    """Columns and cell size (px) of a near-square grid of ``n`` cells over a ``w`` x ``h`` image."""
    cols = math.ceil(math.sqrt(n * w / h))
    rows = math.ceil(n / cols)
    return cols, w / cols, h / rows


def _boxes(p: dict, m: float, c: float) -> dict:
    """The ``mesh`` part of a boxes scene: boxes on an image grid at their depths, camera moving."""
    fx, fy, cx, cy = _intrinsics(p["sensor"])
    w, h = _sensor_size(p["sensor"])
    n = p["box_count"]
    cols, cw, ch = _grid(n, w, h)
    dark, mid = m * (1 - c), m
    boxes = []
    for k in range(n):
        r, q = divmod(k, cols)
        z = p["box_depth_m"][k]
        u, v = (q + 0.5) * cw - 0.5, (r + 0.5) * ch - 0.5
        # at most 0.8 of its cell at its own depth (neighbours at similar depths do not touch; the z-buffer
        # handles any occlusion), and in front of the camera (front face at >= z / 4)
        p["box_size_m"][k] = min(p["box_size_m"][k], 0.8 * min(cw / fx, ch / fy) * z, 1.5 * z)
        size = p["box_size_m"][k]
        boxes.append({"center_m": [(u - cx) * z / fx, (v - cy) * z / fy, z], "size_m": [size] * 3,
                      "face_intensities": [mid, mid, mid, mid, dark, dark]})
    # the image of a point at the mean depth moves at speed_px_s along direction_deg
    z_ref = sum(p["box_depth_m"]) / n
    a = math.radians(p["direction_deg"])
    speed_m_s = p["speed_px_s"] * z_ref / fx
    return {"camera": {"velocity_m_s": [-speed_m_s * math.cos(a), -speed_m_s * math.sin(a), 0.0],
                       "rotation_rpy_deg": [p["angle_deg"], 0.0, 0.0],
                       "angular_velocity_deg_s": [0.0, 0.0, p["angular_velocity_deg_s"]]},
            "boxes": boxes}


def scene_dict(p: dict, *, name: str, seed: int) -> dict:
    """The scene (``sim/SCENES.md`` schema) that parameters ``p`` describe.

    Stripes: one band over all rows, normal at ``angle_deg``, velocity
    ``speed_px_s`` along ``direction_deg``. Shapes: ``shape_count`` shapes on a
    near-square grid of cells, each radius at most 0.45 of its cell (so they
    never overlap; the effective radii are those recorded), moving rigidly.
    Boxes (a ``mesh`` scene): ``box_count`` cubes on a grid of the image at
    their depths (each at most 0.8 of its cell at its depth), front and back
    faces dark, the others at ``m``, on a light background; the camera
    translates so that a point at the boxes' mean depth moves at
    ``speed_px_s`` along ``direction_deg`` in the image, rolls by
    ``angle_deg`` at t = 0 and at ``angular_velocity_deg_s``.
    Intensities: dark ``m (1 - c)``, light ``m (1 + c)`` for mean ``m`` and
    Michelson contrast ``c`` (a light value above 1 is an invalid scene,
    reported by the scene loader).
    """
    m, c = p["mean_intensity"], p["contrast"]
    dark, light = m * (1 - c), m * (1 + c)
    a = math.radians(p["direction_deg"])
    velocity = [p["speed_px_s"] * math.cos(a), p["speed_px_s"] * math.sin(a)]
    scene = {
        "scene": {"name": name, "kind": p["family"], "duration_s": p["duration_s"], "seed": seed,
                  "frame_rate_hz": p["frame_rate_hz"]},
        "sensor": _sensor_table(p["sensor"]),
        "events": {"contrast_pos": p["threshold"], "contrast_neg": p["threshold"],
                   "contrast_sigma": p["threshold_mismatch"], "noise_rate_hz": p["noise_rate_hz"],
                   "refractory_us": p["refractory_us"], "jitter_us": p["jitter_us"]},
    }
    if p["family"] == "stripes":
        scene["scene"]["background"] = m
        scene["stripes"] = [{"period_px": p["period_px"], "angle_deg": p["angle_deg"], "velocity_px_s": velocity,
                             "dark": dark, "light": light}]
        return scene
    if p["family"] == "boxes":
        scene["scene"]["kind"] = "mesh"
        scene["scene"]["background"] = light
        scene.update(_boxes(p, m, c))
        return scene
    w, h = _sensor_size(p["sensor"])
    n = p["shape_count"]
    cols, cw, ch = _grid(n, w, h)
    shapes = []
    for k in range(n):
        r, q = divmod(k, cols)
        p["shape_radius_px"][k] = min(p["shape_radius_px"][k], 0.45 * min(cw, ch))
        shapes.append({"kind": p["shape_kind"][k], "center_px": [(q + 0.5) * cw - 0.5, (r + 0.5) * ch - 0.5],
                       "radius_px": p["shape_radius_px"][k], "rotation_deg": p["angle_deg"], "intensity": dark})
    scene["scene"]["background"] = light
    scene["shapes"] = shapes
    scene["motion"] = {"velocity_px_s": velocity, "angular_velocity_deg_s": p["angular_velocity_deg_s"]}
    return scene


def make_sequence(spec: DatasetSpec, index: int) -> Sequence:
    """Sequence ``index`` of ``spec``: drawn parameters, scene seed and scene dict (not yet validated)."""
    params = draw_parameters(spec, index)
    seed = int(np.random.SeedSequence(spec.seed, spawn_key=(index, _SCENE_SEED_SLOT)).generate_state(1, np.uint64)[0]
               >> np.uint64(1))
    name = spec.sequence_name(index)
    return Sequence(index, name, params, seed, scene_dict(params, name=name, seed=seed))


def sequence_scene(spec: DatasetSpec, seq: Sequence):
    """Validate ``seq.scene`` with the scene loader.

    Messages name ``<spec file>[index]``; the scene's recorded source is
    ``<dataset name>[index]``, which does not depend on where the spec file
    lies, so the recording's bytes do not either.
    """
    scene = parse_scene(seq.scene, source=f"{spec.source}[{seq.index}]")
    return replace(scene, source=f"{spec.name}[{seq.index}]")
