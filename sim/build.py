"""Turn a validated :class:`~evedge.sim.scene.Scene` into a renderer."""

from __future__ import annotations

from .planar import ShapesRenderer, StripesRenderer


def build_renderer(scene):
    """Renderer for ``scene``: analytic for planar kinds, pyrender for ``mesh`` (imported lazily)."""
    s = scene.sensor
    if scene.kind == "stripes":
        return StripesRenderer(s.width, s.height, scene.objects, background=scene.background)
    if scene.kind == "shapes":
        return ShapesRenderer(s.width, s.height, list(scene.objects), scene.motion, background=scene.background)
    if scene.kind == "mesh":
        from .render3d import Box3D, CameraTrajectory, MeshRenderer  # pulls in pyrender / OpenGL

        boxes = [Box3D(**b) for b in scene.objects]
        trajectory = CameraTrajectory(**scene.motion)
        return MeshRenderer(s.width, s.height, s.fx, s.fy, s.cx, s.cy, boxes, trajectory,
                            background=scene.background)
    raise ValueError(f"{scene.source}: key 'scene.kind': unknown kind {scene.kind!r}")
