"""Turn a validated :class:`~evedge.sim.scene.Scene` into a renderer."""

from __future__ import annotations

from .planar import ShapesRenderer, StripesRenderer


def build_trajectory(motion: dict):
    """The camera trajectory of a mesh scene's ``motion`` (see :mod:`evedge.sim.scene3d`)."""
    from .trajectory import CameraTrajectory, KeyframeTrajectory, rotation_from_rpy

    if "times_s" not in motion:
        return CameraTrajectory(**motion)
    return KeyframeTrajectory(motion["times_s"], motion["positions_m"],
                              [rotation_from_rpy(*rpy) for rpy in motion["rotations_rpy_rad"]])


def build_renderer(scene):
    """Renderer for ``scene``: analytic for planar kinds; for ``mesh``, the exact box renderer or
    the pyrender raster one (:mod:`evedge.sim.mesh`), imported lazily."""
    s = scene.sensor
    if scene.kind == "stripes":
        return StripesRenderer(s.width, s.height, scene.objects, background=scene.background)
    if scene.kind == "shapes":
        return ShapesRenderer(s.width, s.height, list(scene.objects), scene.motion, background=scene.background)
    if scene.kind == "mesh":
        trajectory = build_trajectory(scene.motion)
        setup = scene.setup_3d or {"meshes": (), "render": {"method": "exact", "supersample": 2}}
        if setup["render"]["method"] == "exact":
            from .render3d import Box3D, MeshRenderer

            boxes = [Box3D(**b) for b in scene.objects]
            return MeshRenderer(s.width, s.height, s.fx, s.fy, s.cx, s.cy, boxes, trajectory,
                                background=scene.background)
        from .mesh import RasterMeshRenderer, scene_meshes

        return RasterMeshRenderer(s.width, s.height, s.fx, s.fy, s.cx, s.cy,
                                  scene_meshes(scene.objects, setup["meshes"], scene.source), trajectory,
                                  background=scene.background, supersample=setup["render"]["supersample"])
    raise ValueError(f"{scene.source}: key 'scene.kind': unknown kind {scene.kind!r}")
