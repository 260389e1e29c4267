"""Schema of 3-D (``kind = "mesh"``) scene files: camera trajectory, IMU, boxes, meshes, rendering.

Called by :func:`evedge.sim.scene.parse_scene`; the schema is documented in ``sim/SCENES.md``.
Every problem raises :class:`~evedge.sim.scene.SceneError` naming the file and key.
"""

from __future__ import annotations

import math
from pathlib import Path

from .trajectory import GRAVITY_M_S2

#: Mesh primitives a scene can place without a file (built by trimesh).
PRIMITIVES = ("box", "plane", "sphere", "cylinder")
#: Procedural textures generated at load time.
TEXTURES = ("checker", "stripes", "noise")
MESH_SUFFIXES = (".obj", ".glb", ".gltf", ".ply", ".stl", ".off")


def _intensity_list(t, name, count):
    faces = t.raw(name)
    if isinstance(faces, (int, float)) and not isinstance(faces, bool):
        faces = [faces] * count
    if (not isinstance(faces, list) or len(faces) != count
            or not all(isinstance(a, (int, float)) and not isinstance(a, bool) and 0 <= a <= 1 for a in faces)):
        t.fail(name, f"expected {count} numbers in [0, 1] (or one), got {faces!r}")
    return tuple(float(a) for a in faces)


def _camera(cam, duration_s):
    """CameraTrajectory keyword arguments (constant velocity), or ``{"times_s", "positions_m", "rotations_rpy_rad"}``."""
    keys = cam.array_of_tables("keyframes")
    constant = [k for k in ("velocity_m_s", "angular_velocity_deg_s", "position_m", "rotation_rpy_deg") if cam.has(k)]
    if not keys:
        motion = dict(
            position_m=cam.vector("position_m", 3, (0.0, 0.0, 0.0)),
            velocity_m_s=cam.vector("velocity_m_s", 3, (0.0, 0.0, 0.0)),
            rotation_rpy_rad=tuple(math.radians(a) for a in cam.vector("rotation_rpy_deg", 3, (0.0, 0.0, 0.0))),
            angular_velocity_rad_s=tuple(math.radians(a)
                                         for a in cam.vector("angular_velocity_deg_s", 3, (0.0, 0.0, 0.0))),
        )
        return motion
    if constant:
        cam.fail(constant[0], "give either [[camera.keyframes]] or the constant-velocity keys, not both")
    if len(keys) < 2:
        cam.fail("keyframes", f"at least 2 keyframes are needed, got {len(keys)}")
    times, positions, rpy = [], [], []
    for k in keys:
        t = k.number("t_s")
        if times and t <= times[-1]:
            k.fail("t_s", f"keyframe times must increase strictly, got {t} after {times[-1]}")
        times.append(t)
        positions.append(k.vector("position_m", 3))
        rpy.append(tuple(math.radians(a) for a in k.vector("rotation_rpy_deg", 3, (0.0, 0.0, 0.0))))
        k.finish()
    if times[0] > 0 or times[-1] < duration_s:
        cam.fail("keyframes", f"keyframe times [{times[0]}, {times[-1]}] must cover the scene [0, {duration_s}]")
    return dict(times_s=tuple(times), positions_m=tuple(positions), rotations_rpy_rad=tuple(rpy))


def _texture(t):
    kind = t.string("kind", choices=TEXTURES)
    out = dict(kind=kind, dark=t.number("dark", 0.2, lo=0, hi=1), light=t.number("light", 0.8, lo=0, hi=1),
               cells=t.number("cells", 8, lo=1, hi=4096, integer=True),
               resolution_px=t.number("resolution_px", 512, lo=2, hi=8192, integer=True),
               seed=t.number("seed", 0, lo=0, integer=True))
    t.finish()
    return out


def _mesh_entry(t, base: Path):
    has_file, has_prim = t.has("file"), t.has("primitive")
    if has_file == has_prim:
        t.fail("file" if not has_file else "primitive", "give exactly one of 'file' and 'primitive'")
    entry = dict(position_m=t.vector("position_m", 3, (0.0, 0.0, 0.0)),
                 rotation_rpy_rad=tuple(math.radians(a) for a in t.vector("rotation_rpy_deg", 3, (0.0, 0.0, 0.0))),
                 scale=t.number("scale", 1.0, lo=0, lo_open=True))
    if has_file:
        name = t.string("file")
        path = (base / name) if not Path(name).is_absolute() else Path(name)
        if path.suffix.lower() not in MESH_SUFFIXES:
            t.fail("file", f"unknown mesh format {path.suffix!r}; known: {list(MESH_SUFFIXES)}")
        if not path.is_file():
            t.fail("file", f"no such file: {path}")
        entry["file"] = str(path)
    else:
        entry["primitive"] = t.string("primitive", choices=PRIMITIVES)
        entry["size_m"] = t.vector("size_m", 3, (1.0, 1.0, 1.0))
        if min(entry["size_m"]) <= 0:
            t.fail("size_m", f"all sizes must be > 0, got {list(entry['size_m'])}")
    if t.has("texture") and t.has("intensity"):
        t.fail("intensity", "give either 'intensity' (flat) or a [texture] table, not both")
    entry["texture"] = _texture(t.table("texture")) if t.has("texture") else None
    entry["intensity"] = t.number("intensity", -1.0, lo=0, hi=1) if t.has("intensity") else None
    t.finish()
    return entry


def parse_mesh(top, duration_s: float):
    """``(boxes, motion, setup)`` of a mesh scene.

    ``boxes``: tuple of :class:`~evedge.sim.boxes.Box3D` keyword dicts (the scene's ``objects``);
    ``motion``: the camera trajectory (see :func:`evedge.sim.build.build_trajectory`);
    ``setup``: ``{"meshes", "render", "imu"}`` (the scene's ``setup_3d``).
    """
    base = Path(top.source).parent
    cam = top.table("camera", required=True)
    motion = _camera(cam, duration_s)
    cam.finish()
    boxes = []
    for t in top.array_of_tables("boxes"):
        size = t.vector("size_m", 3)
        if min(size) <= 0:
            t.fail("size_m", f"all sizes must be > 0, got {list(size)}")
        boxes.append(dict(center_m=t.vector("center_m", 3), size_m=size,
                          face_intensities=_intensity_list(t, "face_intensities", 6)))
        t.finish()
    meshes = [_mesh_entry(t, base) for t in top.array_of_tables("meshes")]
    if not boxes and not meshes:
        top.fail("boxes", "at least one [[boxes]] or [[meshes]] table is required for kind 'mesh'")
    render = top.table("render")
    method = render.string("method", "auto", choices=("auto", "exact", "raster"))
    if method == "exact" and meshes:
        render.fail("method", "'exact' renders boxes only; scenes with [[meshes]] need 'raster' (or 'auto')")
    supersample = render.number("supersample", 2, lo=1, hi=15, integer=True)
    render.finish()
    imu = top.table("imu")
    imu_cfg = dict(rate_hz=imu.number("rate_hz", 1000.0, lo=0, hi=1e6),
                   gravity_m_s2=imu.vector("gravity_m_s2", 3, GRAVITY_M_S2))
    imu.finish()
    setup = dict(meshes=tuple(meshes),
                 render=dict(method="raster" if (method == "auto" and meshes) else
                             ("exact" if method == "auto" else method), supersample=supersample),
                 imu=imu_cfg)
    return tuple(boxes), motion, setup
