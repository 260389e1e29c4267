"""Turn a validated :class:`~evedge.sim.scene.Scene` into a renderer."""

from __future__ import annotations

from .planar import ShapesRenderer, StripesRenderer


def build_trajectory(motion: dict):
    """The camera trajectory of a mesh scene's ``motion`` (see :mod:`evedge.sim.scene3d`)."""
    from .trajectory import CameraTrajectory, KeyframeTrajectory, rotation_from_rpy

    kwargs = dict(motion)
    kind = kwargs.pop("kind", "constant")
    if kind == "constant":
        return CameraTrajectory(**kwargs)
    return KeyframeTrajectory(kwargs["times_s"], kwargs["positions_m"],
                              [rotation_from_rpy(*rpy) for rpy in kwargs["rotations_rpy_rad"]])


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
        objects = scene.objects
        if objects["render"]["method"] == "exact":
            from .render3d import Box3D, MeshRenderer

            boxes = [Box3D(**b) for b in objects["boxes"]]
            return MeshRenderer(s.width, s.height, s.fx, s.fy, s.cx, s.cy, boxes, trajectory,
                                background=scene.background)
        from .mesh import RasterMeshRenderer, scene_meshes

        return RasterMeshRenderer(s.width, s.height, s.fx, s.fy, s.cx, s.cy,
                                  scene_meshes(objects["boxes"], objects["meshes"], scene.source), trajectory,
                                  background=scene.background, supersample=objects["render"]["supersample"])
    raise ValueError(f"{scene.source}: key 'scene.kind': unknown kind {scene.kind!r}")
