"""The public readers under fuzz: what each is called with and what it may raise.

A target is resolved inside the worker process by a ``"module:function"``
string (as :mod:`evedge.cli` names its subcommands), so the harness imports
none of the packages it exercises.
"""

from __future__ import annotations

import hashlib
import importlib
import json
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np


def _resolve(spec: str):
    module, attr = spec.split(":")
    return getattr(importlib.import_module(module), attr)


def recording_digest(rec) -> str:
    """sha256 over everything a recording holds except where it was read from."""
    h = hashlib.sha256()
    h.update(f"{rec.sensor_size.width}x{rec.sensor_size.height}".encode())
    h.update(np.ascontiguousarray(rec.events).tobytes())
    for stack in (rec.frames, rec.edges):
        if stack is not None:
            h.update(stack.images.dtype.str.encode() + repr(stack.images.shape).encode())
            h.update(np.ascontiguousarray(stack.t_us).tobytes() + np.ascontiguousarray(stack.images).tobytes())
    if rec.truth is not None:
        h.update(rec.truth.dtype.descr.__repr__().encode() + np.ascontiguousarray(rec.truth).tobytes())
    meta = {k: v for k, v in rec.metadata.items() if k not in ("source", "frames_source")}
    h.update(json.dumps(meta, sort_keys=True, default=str).encode())
    return h.hexdigest()


def check_recording(rec, case: dict) -> str | None:
    """A read recording must hold what its documented domain allows (and its seed's content)."""
    from evedge.events import Recording, validate_events

    if not isinstance(rec, Recording):
        return f"returned {type(rec).__name__}, not a Recording"
    try:
        validate_events(rec.events, rec.sensor_size)
    except ValueError as err:
        return f"events invalid: {err}"
    for name in ("frames", "edges"):
        stack = getattr(rec, name)
        if stack is None:
            continue
        if stack.images.shape[1:] != rec.sensor_size.shape:
            return f"{name} are {stack.images.shape[1:]}, sensor is {rec.sensor_size.shape}"
        if np.any(stack.t_us[1:] < stack.t_us[:-1]):
            return f"{name} times decrease"
        img = stack.images
        if name == "edges" and img.dtype != np.bool_:
            return f"edges of dtype {img.dtype}"
        if name == "frames" and img.dtype != np.uint8:
            if img.dtype.kind != "f" or (img.size and not (np.isfinite(img).all() and img.min() >= 0 and img.max() <= 1)):
                return f"frames of dtype {img.dtype} outside [0, 1] or not finite"
    expect = case.get("expect_digest")
    if expect and recording_digest(rec) != expect:
        return "a corrupted file was read as a different recording"
    return None


def _consume(iterator) -> int:
    return sum(chunk.size for chunk in iterator)


@dataclass(frozen=True)
class Target:
    """A reader under fuzz.

    Attributes
    ----------
    function : str
        ``"module:function"``.
    kwargs : dict
        Extra arguments (``sensor_size`` as ``"WxH"`` text).
    errors : str
        ``"module:Class"`` of the documented error type.
    check : callable or None
        ``check(value, case) -> problem or None`` on a returned value.
    wrap : callable or None
        Applied to the returned value first (e.g. to drain an iterator).
    """

    function: str
    errors: str
    kwargs: tuple = ()
    check: Callable | None = None
    wrap: Callable | None = None

    def call(self, path: str):
        kwargs = dict(self.kwargs)
        if "sensor_size" in kwargs:
            from evedge.events import SensorSize

            kwargs["sensor_size"] = SensorSize.parse(kwargs["sensor_size"])
        value = _resolve(self.function)(path, **kwargs)
        return self.wrap(value) if self.wrap else value

    @property
    def error_types(self):
        return _resolve(self.errors)


def selftest(path: str):
    """A target that misbehaves as its input says (the harness's own tests).

    The file holds one word: ``ok``, ``error``, ``unnamed``, ``keyerror``,
    ``panic`` (a ``BaseException``), ``alloc`` (8 GiB), ``abort`` (SIGABRT)
    or ``hang``.
    """
    import os
    import time

    word = open(path).read().strip()
    if word == "error":
        raise ValueError(f"{path}: a documented error")
    if word == "unnamed":
        raise ValueError("an error that does not say where")
    if word == "keyerror":
        raise KeyError("deep inside")
    if word == "panic":
        raise BaseException("like pyo3_runtime.PanicException")
    if word == "alloc":
        return bytearray(8 * 2**30)
    if word == "abort":
        os.abort()
    if word == "hang":
        while True:
            time.sleep(1)
    return word


_EVENT_FILE_ERROR = "evedge.io:EventFileError"
#: Registered formats fuzzed through :func:`evedge.io.read_events` (seeds in :mod:`.corpus`).
NATIVE_FORMATS = ("evt3", "evt2", "dat", "es", "aedat2", "aedat3")
#: Mesh file formats of 3-D scenes (seeds exported by trimesh in :mod:`.corpus`).
MESH_FORMATS = ("obj", "ply", "glb")

#: name -> Target; the harness fuzzes each with its own corpus (:mod:`evedge._fuzz.corpus`).
TARGETS = {
    "ecd_text": Target("evedge.io:read_ecd", _EVENT_FILE_ERROR, (("sensor_size", "240x180"),), check_recording),
    "ecd_folder": Target("evedge.io:read_ecd", _EVENT_FILE_ERROR, (), check_recording),
    "mat": Target("evedge.io:read_mat", _EVENT_FILE_ERROR, (), check_recording),
    "hdf5": Target("evedge.io:read_hdf5", _EVENT_FILE_ERROR, (), check_recording),
    "hdf5_any": Target("evedge.io:read_events", _EVENT_FILE_ERROR, (), check_recording),
    "hdf5_stream": Target("evedge.io:iter_hdf5_events", _EVENT_FILE_ERROR, (), None, _consume),
    "aedat4": Target("evedge.io:read_aedat4", _EVENT_FILE_ERROR, (), check_recording),
    "scene": Target("evedge.sim.scene:load_scene", "evedge.sim.scene:SceneError"),
    "dataset_spec": Target("evedge.sim.dataset:load_dataset", "evedge.sim.scene:SceneError"),
    # the formats of evedge.io's registry beyond the four above, read through read_events
    **{name: Target("evedge.io:read_events", _EVENT_FILE_ERROR, (("format", name),), check_recording)
       for name in NATIVE_FORMATS},
    "detection": Target("evedge.io.detection:read_detection", _EVENT_FILE_ERROR),
    # user meshes of 3-D scenes (OBJ, PLY, GLB through trimesh): a ValueError naming the file
    **{f"mesh_{fmt}": Target("evedge.sim.mesh:load_mesh_file", "builtins:ValueError") for fmt in MESH_FORMATS},
}

#: Targets outside the campaign: the harness's own checks.
SELF_TARGETS = {"selftest": Target("evedge._fuzz.targets:selftest", "builtins:ValueError")}


# ---------------------------------------------------------------- frames and video inputs of `evedge simulate`


@dataclass(frozen=True)
class FramesRun:
    """What the frames/video targets give: the simulated recording and a digest of every decoded frame."""

    recording: object
    frames_digest: str


def _frames_run(source) -> FramesRun:
    """Simulate ``source`` as ``evedge simulate`` does (the frames are decoded lazily, mid-run), then hash them."""
    rec = _resolve("evedge.sim.frames:simulate_frames")(source, progress=False)
    h = hashlib.sha256()
    for k in range(len(source)):
        h.update(np.ascontiguousarray(source.frame(k)).tobytes())
    source.close()
    h.update(np.ascontiguousarray(source.times_s).tobytes())
    return FramesRun(rec, h.hexdigest())


def frames_folder(path: str) -> FramesRun:
    """``evedge simulate --frames DIR``: :func:`~evedge.sim.frames.open_frames_folder` and a run."""
    return _frames_run(_resolve("evedge.sim.frames:open_frames_folder")(path))


def video_file(path: str) -> FramesRun:
    """``evedge simulate --video FILE [--timestamps timestamps.txt]`` (when the case holds a timestamps file)."""
    from pathlib import Path

    ts = Path(path).with_name("timestamps.txt")
    return _frames_run(_resolve("evedge.sim.frames:open_video")(path, timestamps=ts if ts.is_file() else None))


def check_frames_run(run: FramesRun, case: dict) -> str | None:
    """Events valid for the sensor, truth in its documented domain, and an intact frame when it must be."""
    from evedge.events import validate_events

    rec = run.recording
    try:
        validate_events(rec.events, rec.sensor_size)
    except ValueError as err:
        return f"events invalid: {err}"
    tr = rec.truth
    if tr is None or tr.shape != rec.events.shape:
        return "truth missing or not one row per event"
    # frames carry no motion field: flow, normal and lifetime are NaN on every row; the rest is finite
    for name in ("vx_px_s", "vy_px_s", "nx", "ny", "lifetime_us"):
        if not np.all(np.isnan(tr[name])):
            return f"truth {name} not NaN"
    if tr["is_signal"].dtype != np.bool_:
        return "truth is_signal not boolean"
    # t_ns is the event's instant in ns; t (us) is it rounded (events within one us are in pixel order), both
    # from the same float64 seconds: up to a few of its ulps apart late in a long run
    tol = 500 + 2e9 * np.spacing(np.abs(tr["t_ns"]) / 1e9)
    if np.any(np.abs(tr["t_ns"] - rec.events["t"].astype(np.int64) * 1000) > tol):
        return "truth t_ns is not the events' times"
    expect = case.get("expect_digest")
    if expect and run.frames_digest != expect:
        return "a damaged image was read as a different frame"
    return None


_FRAMES_ERROR = "evedge.sim.frames:FramesError"
TARGETS["frames"] = Target("evedge._fuzz.targets:frames_folder", _FRAMES_ERROR, (), check_frames_run)
TARGETS["video"] = Target("evedge._fuzz.targets:video_file", _FRAMES_ERROR, (), check_frames_run)
