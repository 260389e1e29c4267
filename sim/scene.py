"""Scene files: TOML read with ``tomllib``, validated, turned into a renderer.

The schema is documented in ``sim/SCENES.md``. Every problem raises
:class:`SceneError` (a ``ValueError``) whose message names the file, the key
(dotted path, e.g. ``shapes[2].radius_px``) and the problem.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from evedge.sensors import SENSOR_MODELS

from .converter import ConverterParams

#: Sensor presets: size and pinhole intrinsics (fx, fy, cx, cy) in px, from
#: :data:`evedge.sensors.SENSOR_MODELS` (davis240: the Event Camera Dataset's
#: calibration of its DAVIS240C; the others a nominal lens).
SENSOR_PRESETS = {name: dict(width=m.width, height=m.height, fx=m.fx, fy=m.fy, cx=m.cx, cy=m.cy)
                  for name, m in SENSOR_MODELS.items()}

SCENE_KINDS = ("stripes", "shapes", "mesh")
#: Longest scene: the truth's times are int64 nanoseconds (2**63 ns is about 9.22e9 s; events' us go further).
MAX_DURATION_S = 9e9
SHAPE_KINDS = ("triangle", "square", "hexagon", "star", "circle", "polygon")


def _finite(v) -> bool:
    try:
        return math.isfinite(v)
    except OverflowError:  # an integer beyond any float
        return False


class SceneError(ValueError):
    """A scene file or dict is invalid; the message names file, key and problem."""


class _Table:
    """A TOML table being read: typed getters, and a check that no unknown key is left."""

    def __init__(self, source: str, prefix: str, data: Any):
        self.source = source
        self.prefix = prefix
        if not isinstance(data, dict):
            raise SceneError(f"{source}: key '{prefix}': expected a table, got {type(data).__name__}")
        self.data = data
        self.used: set[str] = set()

    def key(self, name: str) -> str:
        return f"{self.prefix}.{name}" if self.prefix else name

    def fail(self, name: str, problem: str):
        raise SceneError(f"{self.source}: key '{self.key(name)}': {problem}")

    def has(self, name: str) -> bool:
        return name in self.data

    def _lookup(self, name: str, default):
        """Mark ``name`` read; ``(True, value)`` when present, else ``(False, default)``.

        A ``default`` of None means the key is required: its absence fails.
        """
        self.used.add(name)
        if name in self.data:
            return True, self.data[name]
        if default is None:
            self.fail(name, "missing (required)")
        return False, default

    def raw(self, name: str, default=None):
        self.used.add(name)
        return self.data.get(name, default)

    def number(self, name: str, default=None, *, lo=None, hi=None, lo_open=False, integer=False):
        present, v = self._lookup(name, default)
        if not present:
            return v
        ok = (isinstance(v, int) if integer else isinstance(v, (int, float))) and not isinstance(v, bool)
        if not ok:
            self.fail(name, f"expected {'an integer' if integer else 'a number'}, got {v!r}")
        try:
            finite = math.isfinite(v)
        except OverflowError:  # an integer beyond any float
            finite = False
        if not finite:
            self.fail(name, f"must be finite, got {v if isinstance(v, float) else f'an integer of {len(str(abs(v)))} digits'}")
        if lo is not None and (v <= lo if lo_open else v < lo):
            self.fail(name, f"must be {'>' if lo_open else '>='} {lo}, got {v!r}")
        if hi is not None and v > hi:
            self.fail(name, f"must be <= {hi}, got {v!r}")
        return int(v) if integer else float(v)

    def string(self, name: str, default=None, *, choices=None):
        present, v = self._lookup(name, default)
        if not present:
            return v
        if not isinstance(v, str):
            self.fail(name, f"expected a string, got {v!r}")
        if choices is not None and v not in choices:
            self.fail(name, f"must be one of {list(choices)}, got {v!r}")
        return v

    def boolean(self, name: str, default=None) -> bool:
        present, v = self._lookup(name, default)
        if present and not isinstance(v, bool):
            self.fail(name, f"expected true or false, got {v!r}")
        return bool(v)

    def vector(self, name: str, length: int, default=None):
        present, v = self._lookup(name, default)
        if not present:
            return tuple(v)
        if (not isinstance(v, list) or len(v) != length
                or not all(isinstance(a, (int, float)) and not isinstance(a, bool) and _finite(a) for a in v)):
            self.fail(name, f"expected an array of {length} finite numbers, got {v!r}")
        return tuple(float(a) for a in v)

    def table(self, name: str, required=False) -> "_Table":
        self.used.add(name)
        if name not in self.data:
            if required:
                self.fail(name, "missing table (required)")
            return _Table(self.source, self.key(name), {})
        return _Table(self.source, self.key(name), self.data[name])

    def array_of_tables(self, name: str) -> list["_Table"]:
        self.used.add(name)
        v = self.data.get(name, [])
        if not isinstance(v, list):
            self.fail(name, f"expected an array of tables ([[{name}]]), got {type(v).__name__}")
        return [_Table(self.source, f"{self.key(name)}[{i}]", item) for i, item in enumerate(v)]

    def finish(self) -> None:
        unknown = sorted(set(self.data) - self.used)
        if unknown:
            self.fail(unknown[0], f"unknown key (allowed here: {sorted(self.used)})")


@dataclass(frozen=True)
class Sensor:
    """Sensor size and pinhole intrinsics (px)."""

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float


@dataclass(frozen=True)
class Section:
    """A named time range of a scene (e.g. the slow and fast parts of shapes_translation)."""

    name: str
    start_s: float
    end_s: float


@dataclass(frozen=True)
class Scene:
    """A validated scene: everything :func:`evedge.sim.simulate` needs.

    ``raw`` is the parsed TOML (kept for the recording's metadata) and
    ``source`` the file name used in messages.
    """

    name: str
    kind: str
    source: str
    duration_s: float
    seed: int
    frame_rate_hz: float
    sensor: Sensor
    params: ConverterParams
    background: float
    objects: tuple = ()
    motion: Any = None
    sections: tuple[Section, ...] = ()
    description: str = ""
    raw: dict = field(default_factory=dict, compare=False, repr=False)
    #: mesh scenes: ``{"meshes", "render", "imu"}`` (see :mod:`evedge.sim.scene3d`); empty otherwise
    setup_3d: dict = field(default_factory=dict, compare=False, repr=False)

    def build_renderer(self):
        """A renderer for this scene (imports the 3-D renderer only for ``mesh`` scenes)."""
        from .build import build_renderer
        return build_renderer(self)


def _sensor(t: _Table) -> Sensor:
    preset = t.string("preset", "") if t.has("preset") else ""
    if preset and preset not in SENSOR_PRESETS:
        t.fail("preset", f"unknown preset {preset!r}; known: {sorted(SENSOR_PRESETS)}")
    base = dict(SENSOR_PRESETS[preset]) if preset else {}
    if not preset and not (t.has("width") and t.has("height")):
        t.fail("width" if not t.has("width") else "height", "give a preset or both width and height")
    w = t.number("width", base.get("width"), lo=1, hi=32767, integer=True)
    h = t.number("height", base.get("height"), lo=1, hi=32767, integer=True)
    if "width" in t.data or "height" in t.data:
        # another size: the preset's intrinsics no longer apply
        for k in ("fx", "fy", "cx", "cy"):
            base.pop(k, None)
    f_default = base.get("fx", float(w))
    fx = t.number("fx", f_default, lo=0, lo_open=True)
    fy = t.number("fy", base.get("fy", fx), lo=0, lo_open=True)
    cx = t.number("cx", base.get("cx", (w - 1) / 2))
    cy = t.number("cy", base.get("cy", (h - 1) / 2))
    t.finish()
    return Sensor(w, h, fx, fy, cx, cy)


def _params(t: _Table) -> ConverterParams:
    d = ConverterParams()
    if t.has("preset"):
        # a sensor's typical pixel settings (evedge.sensors); the keys below still override them
        name = t.string("preset", "")
        if name not in SENSOR_MODELS:
            t.fail("preset", f"unknown preset {name!r}; known: {sorted(SENSOR_MODELS)}")
        d = ConverterParams(**SENSOR_MODELS[name].event_params)
    if t.has("effects"):
        # a realistic sensor-effect preset (v2e's); explicit keys below still override it
        from .converter import SENSOR_EFFECT_PRESETS

        name = t.string("effects", "")
        if name not in SENSOR_EFFECT_PRESETS:
            t.fail("effects", f"unknown effects preset {name!r}; known: {sorted(SENSOR_EFFECT_PRESETS)}")
        d = replace(d, **SENSOR_EFFECT_PRESETS[name])
    kw = dict(
        contrast_pos=t.number("contrast_pos", d.contrast_pos, lo=0, lo_open=True),
        contrast_neg=t.number("contrast_neg", d.contrast_neg, lo=0, lo_open=True),
        contrast_sigma=t.number("contrast_sigma", d.contrast_sigma, lo=0),
        min_contrast=t.number("min_contrast", d.min_contrast, lo=0, lo_open=True),
        refractory_us=t.number("refractory_us", d.refractory_us, lo=0),
        noise_rate_hz=t.number("noise_rate_hz", d.noise_rate_hz, lo=0, hi=1e6),
        jitter_us=t.number("jitter_us", d.jitter_us, lo=0, hi=1e12),
        log_eps=t.number("log_eps", d.log_eps, lo=0, lo_open=True),
        lambda_=t.number("lambda", d.lambda_, lo=0, lo_open=True, hi=1.0),
        min_rate_hz=t.number("min_rate_hz", d.min_rate_hz, lo=0, lo_open=True, hi=1e6),
        max_step_px=t.number("max_step_px", d.max_step_px, lo=0, lo_open=True),
        min_step_s=t.number("min_step_s", d.min_step_s, lo=1e-9),  # below, t + step == t: no progress
        sampling=t.string("sampling", d.sampling, choices=("auto", "verified", "predicted", "geometric")),
        crossing_times=t.string("crossing_times", d.crossing_times, choices=("auto", "exact", "linear")),
        lowpass_cutoff_hz=t.number("lowpass_cutoff_hz", d.lowpass_cutoff_hz, lo=0, hi=1e9),
        leak_rate_hz=t.number("leak_rate_hz", d.leak_rate_hz, lo=0, hi=1e6),
        leak_rate_sigma=t.number("leak_rate_sigma", d.leak_rate_sigma, lo=0),
        shot_noise_rate_hz=t.number("shot_noise_rate_hz", d.shot_noise_rate_hz, lo=0, hi=1e6),
        noise_resets=t.boolean("noise_resets", d.noise_resets),
    )
    t.finish()
    return ConverterParams(**kw)


def _stripes(top: _Table, sensor: Sensor):
    from .planar import StripeLayer

    tables = top.array_of_tables("stripes")
    if not tables:
        top.fail("stripes", "at least one [[stripes]] table is required for kind 'stripes'")
    layers = []
    for t in tables:
        rows = t.vector("rows_fraction", 2, (0.0, 1.0))
        if not (0.0 <= rows[0] < rows[1] <= 1.0):
            t.fail("rows_fraction", f"must satisfy 0 <= start < end <= 1, got {list(rows)}")
        r0, r1 = int(round(rows[0] * sensor.height)), int(round(rows[1] * sensor.height))
        if r1 <= r0:
            t.fail("rows_fraction", f"covers no pixel row on a {sensor.height}-row sensor")
        dark = t.number("dark", 0.2, lo=0, hi=1)
        light = t.number("light", 0.8, lo=0, hi=1)
        duty = t.number("duty", 0.5, lo=0, lo_open=True)
        if duty >= 1:
            t.fail("duty", f"must be < 1, got {duty}")
        layers.append(StripeLayer(
            rows=(r0, r1),
            period_px=t.number("period_px", lo=0, lo_open=True),
            angle_rad=math.radians(t.number("angle_deg", 0.0)),
            velocity_px_s=t.vector("velocity_px_s", 2),
            dark=dark, light=light, duty=duty,
            phase_px=t.number("phase_px", 0.0),
        ))
        t.finish()
    for i, a in enumerate(layers):
        for b in layers[:i]:
            if a.rows[0] < b.rows[1] and b.rows[0] < a.rows[1]:
                tables[i].fail("rows_fraction", f"rows {a.rows} overlap another stripes layer {b.rows}")
    return tuple(layers)


def _shapes(top: _Table):
    from .planar import Circle, Polygon, regular_polygon, star_polygon

    tables = top.array_of_tables("shapes")
    if not tables:
        top.fail("shapes", "at least one [[shapes]] table is required for kind 'shapes'")
    out = []
    for t in tables:
        kind = t.string("kind", choices=SHAPE_KINDS)
        value = t.number("intensity", 0.2, lo=0, hi=1)
        if kind == "polygon":
            verts = t.raw("vertices_px")
            if verts is None:
                t.fail("vertices_px", "missing (required for kind 'polygon')")
            try:
                v = np.asarray(verts, dtype=np.float64)
            except (TypeError, ValueError):
                t.fail("vertices_px", f"expected an array of [x, y] pairs, got {verts!r}")
            if v.ndim != 2 or v.shape[1] != 2 or v.shape[0] < 3 or not np.all(np.isfinite(v)):
                t.fail("vertices_px", f"expected at least 3 finite [x, y] pairs, got {verts!r}")
            out.append(Polygon(v, value))
            t.finish()
            continue
        center = t.vector("center_px", 2)
        radius = t.number("radius_px", lo=0, lo_open=True)
        rot = math.radians(t.number("rotation_deg", 0.0))
        if kind == "circle":
            out.append(Circle(center, radius, value))
        elif kind == "star":
            points = t.number("points", 5, lo=3, integer=True)
            inner = t.number("inner_ratio", 0.45, lo=0, lo_open=True)
            if inner >= 1:
                t.fail("inner_ratio", f"must be < 1, got {inner}")
            out.append(Polygon(star_polygon(center, radius, points, inner, rot), value))
        else:
            sides = {"triangle": 3, "square": 4, "hexagon": 6}[kind]
            out.append(Polygon(regular_polygon(center, radius, sides, rot), value))
        t.finish()
    return tuple(out)


def _motion(t: _Table, sensor: Sensor):
    from .motion import PlanarMotion

    m = PlanarMotion(
        center_px=t.vector("center_px", 2, ((sensor.width - 1) / 2, (sensor.height - 1) / 2)),
        velocity_px_s=t.vector("velocity_px_s", 2, (0.0, 0.0)),
        acceleration_px_s2=t.vector("acceleration_px_s2", 2, (0.0, 0.0)),
        amplitude_px=t.vector("amplitude_px", 2, (0.0, 0.0)),
        angle_rad=math.radians(t.number("angle_deg", 0.0)),
        angular_velocity_rad_s=math.radians(t.number("angular_velocity_deg_s", 0.0)),
        angular_acceleration_rad_s2=math.radians(t.number("angular_acceleration_deg_s2", 0.0)),
        angle_amplitude_rad=math.radians(t.number("angle_amplitude_deg", 0.0)),
        frequency_hz=t.number("frequency_hz", 0.0, lo=0),
        chirp_hz_s=t.number("chirp_hz_s", 0.0, lo=0),
    )
    t.finish()
    return m


def parse_scene(data: dict, source: str = "<scene>") -> Scene:
    """Validate a scene dict (the parsed TOML) and return a :class:`Scene`.

    Parameters
    ----------
    data : dict
        The scene, as :func:`tomllib.loads` gives it (schema in ``sim/SCENES.md``).
    source : str
        The file name quoted in messages (and the default scene name's stem).

    Returns
    -------
    Scene

    Raises
    ------
    SceneError
        With a message naming ``source``, the key and the problem.
    """
    top = _Table(source, "", data)
    head = top.table("scene", required=True)
    name = head.string("name", Path(source).stem)
    kind = head.string("kind", choices=SCENE_KINDS)
    duration = head.number("duration_s", lo=0, lo_open=True, hi=MAX_DURATION_S)
    seed = head.number("seed", 0, lo=0, integer=True)
    frame_rate = head.number("frame_rate_hz", 100.0, lo=0, hi=1e6)  # frame times are whole microseconds
    background = head.number("background", 0.8 if kind == "shapes" else 0.5, lo=0, hi=1)
    description = head.string("description", "")
    head.finish()
    sensor = _sensor(top.table("sensor", required=True))
    params = _params(top.table("events"))
    sections = []
    for t in top.array_of_tables("sections"):
        s = Section(t.string("name"), t.number("start_s", lo=0), t.number("end_s", lo=0))
        if s.end_s <= s.start_s:
            t.fail("end_s", f"must be > start_s ({s.start_s}), got {s.end_s}")
        if s.end_s > duration + 1e-12:
            t.fail("end_s", f"must be <= scene.duration_s ({duration}), got {s.end_s}")
        t.finish()
        sections.append(s)
    motion = None
    setup_3d = {}
    if kind == "stripes":
        objects = _stripes(top, sensor)
    elif kind == "shapes":
        objects = _shapes(top)
        motion = _motion(top.table("motion"), sensor)
    else:
        from .scene3d import parse_mesh  # camera trajectory, boxes, meshes, IMU (3-D schema)

        objects, motion, setup_3d = parse_mesh(top, duration)
    top.finish()
    return Scene(name=name, kind=kind, source=source, duration_s=duration, seed=seed, frame_rate_hz=frame_rate,
                 sensor=sensor, params=params, background=background, objects=objects, motion=motion,
                 sections=tuple(sections), description=description, raw=data, setup_3d=setup_3d)


def with_sensor(scene: Scene, preset: str) -> Scene:
    """``scene`` re-validated on the sensor preset ``preset`` (its own ``[sensor]`` table replaced).

    Scene coordinates (shape centres, ...) stay in pixels; fractions of the
    image (stripe bands) follow the new size.

    Parameters
    ----------
    scene : Scene
    preset : str
        A name of :data:`evedge.sensors.SENSOR_MODELS`.

    Returns
    -------
    Scene

    Raises
    ------
    SceneError
        Unknown preset (named with the known ones).

    Examples
    --------
    >>> s = with_sensor(load_scene("scenes/stripes.toml"), "gen4")  # doctest: +SKIP
    >>> (s.sensor.width, s.sensor.height)  # doctest: +SKIP
    (1280, 720)
    """
    data = dict(scene.raw)
    data["sensor"] = {"preset": str(preset).strip().lower()}
    return parse_scene(data, source=scene.source)


def load_scene(path) -> Scene:
    """Read and validate a scene file (TOML, schema in ``sim/SCENES.md``).

    Parameters
    ----------
    path : path-like
        The scene file.

    Returns
    -------
    Scene

    Raises
    ------
    SceneError
        Unreadable file, invalid TOML or UTF-8, or any invalid key (named).
    """
    path = Path(path)
    _, data = _read_toml(path, "scene file")
    return parse_scene(data, source=str(path))


def _read_toml(path: Path, what: str, error: type[SceneError] = SceneError) -> tuple[str, dict]:
    """Text and parsed table of the TOML file ``path`` (scene, dataset and sweep specs alike).

    Raises ``error`` naming ``path``: ``cannot read <what>`` (unreadable) or ``not valid TOML``
    (invalid TOML or UTF-8).
    """
    try:
        text = path.read_bytes().decode("utf-8")
        data = tomllib.loads(text)
    except OSError as exc:
        raise error(f"{path}: cannot read {what}: {exc.strerror or exc}") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise error(f"{path}: not valid TOML: {exc}") from None
    return text, data
