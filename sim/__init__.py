"""evedge.sim: event-camera simulator with exact ground truth.

Scenes (TOML, schema in ``sim/SCENES.md``) are rendered analytically (planar
scenes and 3-D box scenes: exact per-pixel area coverage) or with pyrender
(3-D textured meshes),
sampled adaptively and converted to events ESIM-style, with per-event ground
truth (flow, gradient direction, lifetime) in :data:`TRUTH_DTYPE`.

Main entry points: :func:`simulate`, :func:`load_scene`, :func:`parse_scene`;
a user's video or frames: :func:`simulate_frames` with :func:`open_video` or
:func:`open_frames_folder` (:mod:`evedge.sim.frames`).
"""

from .converter import ConverterParams, EventConverter
from .frames import FramesError, frames_from_arrays, open_frames_folder, open_video, simulate_frames
from .renderer import GeometricTruth, Renderer
from .scene import SENSOR_PRESETS, Scene, SceneError, load_scene, parse_scene
from .simulate import edge_map, render_frame, simulate, thin_edge_map
from .truth import TRUTH_DTYPE

__all__ = [
    "ConverterParams", "EventConverter", "GeometricTruth", "Renderer", "SENSOR_PRESETS", "Scene",
    "SceneError", "TRUTH_DTYPE", "edge_map", "load_scene", "parse_scene", "render_frame", "simulate",
    "thin_edge_map",
    "FramesError", "frames_from_arrays", "open_frames_folder", "open_video", "simulate_frames",
]
