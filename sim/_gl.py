"""pyrender/EGL plumbing shared by the 3-D renderers: lazy import, single-sample framebuffers, clean deletion,
and their common camera set-up and life cycle (:class:`_PinholeRenderer`).

Importing this module touches no OpenGL; :func:`_import_pyrender` does, setting
``PYOPENGL_PLATFORM=egl`` and ``PYGLET_HEADLESS=1`` first (only if unset).
"""

from __future__ import annotations

import os

import numpy as np

from .trajectory import _finite, _Trajectory

# Clip planes of the OpenGL camera. The near plane clips geometry closer than 5 cm; a 24-bit
# depth buffer with these planes resolves 0.1 mm at 5 m, ample for the occlusion test (depth
# values themselves are computed analytically, not read back, by the box renderer).
ZNEAR_M = 0.05
ZFAR_M = 1000.0


def opencv_to_gl_pose(pose: np.ndarray) -> np.ndarray:
    """Camera-to-world pose with OpenCV camera axes (y down, looks +z) as OpenGL's (y up, looks -z)."""
    pose = np.array(pose, dtype=np.float64)
    pose[:3, 1:3] *= -1.0
    return pose


def _import_pyrender():
    """Import pyrender for headless EGL rendering (lazily: importing OpenGL has side effects)."""
    os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
    os.environ.setdefault("PYGLET_HEADLESS", "1")
    if not hasattr(np, "infty"):
        # numpy 2 removed np.infty, which pyrender.mesh still uses (bounds, centroid)
        np.infty = np.inf
    import pyrender
    from OpenGL import GL

    return pyrender, GL


def _single_sample_renderer_class(pyrender, GL):
    """A pyrender Renderer whose main framebuffer has one sample per pixel.

    pyrender always draws into a 4x multisampled framebuffer and resolves it, which blends
    the colours of the faces meeting in a pixel; face identifiers encoded as colours must not
    be blended, so the multisampled renderbuffers are re-allocated with 0 samples (which
    OpenGL defines as single-sample storage) right after pyrender creates them.
    """

    class _SingleSampleRenderer(pyrender.Renderer):
        _respecified = None

        def _configure_main_framebuffer(self):
            super()._configure_main_framebuffer()
            if self._main_cb_ms is not self._respecified:
                w, h = self.viewport_width, self.viewport_height
                GL.glBindRenderbuffer(GL.GL_RENDERBUFFER, self._main_cb_ms)
                GL.glRenderbufferStorageMultisample(GL.GL_RENDERBUFFER, 0, GL.GL_RGBA, w, h)
                GL.glBindRenderbuffer(GL.GL_RENDERBUFFER, self._main_db_ms)
                GL.glRenderbufferStorageMultisample(
                    GL.GL_RENDERBUFFER, 0, GL.GL_DEPTH_COMPONENT24, w, h
                )
                self._respecified = self._main_cb_ms

    return _SingleSampleRenderer


def _delete_offscreen(renderer) -> None:
    """Free an OffscreenRenderer's GL objects and context without terminating the EGL display.

    pyrender's ``OffscreenRenderer.delete`` calls ``eglTerminate`` on the display, which is one
    per device and shared by every renderer of the process: it would invalidate the contexts of
    all other live renderers. Here only this renderer's context is destroyed.
    """
    platform = renderer._platform
    try:
        platform.make_current()
        renderer._renderer.delete()
    finally:
        display = getattr(platform, "_egl_display", None)
        context = getattr(platform, "_egl_context", None)
        if display is not None and context is not None:
            from OpenGL.EGL import EGL_NO_CONTEXT, EGL_NO_SURFACE, eglDestroyContext, eglMakeCurrent

            eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT)
            eglDestroyContext(display, context)
            platform._egl_context = None
            platform._egl_display = None
        else:  # other platforms (OSMesa, pyglet) own their context alone
            platform.delete_context()
        # OffscreenRenderer.__del__ calls delete(), which then fails harmlessly (and silently)
        renderer._renderer = None
        renderer._platform = None


def _grey_renderer_class(pyrender, GL, samples: int):
    """A pyrender Renderer that draws with ``samples`` multisamples (0: none) into one 8-bit
    channel and reads back only that (uint8, rows top-down), without the depth buffer.

    pyrender draws into RGBA8 buffers, reads colour and depth and linearises the depth in
    Python for every render; the grey renderers need one 8-bit channel, so the colour
    renderbuffers (multisampled and resolved) are re-allocated as ``GL_R8`` (a quarter of the
    memory to clear, write and resolve: measured 1.5x the renders/s of RGBA8 at 2x2 x 4 MSAA,
    240x180, llvmpipe) and only it is read back. The multisampled renderbuffers get ``samples``
    and the count the GL stack actually gave is checked (an implementation may round a request
    up, e.g. Mesa llvmpipe gives 4 for 2, or refuse counts above ``GL_MAX_SAMPLES``, 4 on
    llvmpipe): a mismatch is a ``ValueError`` naming ``multisample``, not a silently different
    sampling.
    """

    class _GreyRenderer(pyrender.Renderer):
        _respecified = None

        def _configure_main_framebuffer(self):
            super()._configure_main_framebuffer()
            if self._main_cb_ms is not self._respecified:
                w, h = self.viewport_width, self.viewport_height
                limit = int(GL.glGetIntegerv(GL.GL_MAX_SAMPLES))
                name = GL.glGetString(GL.GL_RENDERER).decode(errors="replace")
                if samples > limit:
                    raise ValueError(f"multisample={samples}: this OpenGL stack ({name}) supports at most "
                                     f"GL_MAX_SAMPLES = {limit}")
                GL.glBindRenderbuffer(GL.GL_RENDERBUFFER, self._main_cb_ms)
                GL.glRenderbufferStorageMultisample(GL.GL_RENDERBUFFER, samples, GL.GL_R8, w, h)
                got = int(GL.glGetRenderbufferParameteriv(GL.GL_RENDERBUFFER, GL.GL_RENDERBUFFER_SAMPLES))
                if got != samples:
                    raise ValueError(f"multisample={samples}: this OpenGL stack ({name}) allocates {got} samples "
                                     f"for that request (GL_MAX_SAMPLES = {limit}); ask for a count it supports")
                GL.glBindRenderbuffer(GL.GL_RENDERBUFFER, self._main_db_ms)
                GL.glRenderbufferStorageMultisample(GL.GL_RENDERBUFFER, samples, GL.GL_DEPTH_COMPONENT24, w, h)
                GL.glBindRenderbuffer(GL.GL_RENDERBUFFER, self._main_cb)  # the resolve target, same format
                GL.glRenderbufferStorage(GL.GL_RENDERBUFFER, GL.GL_R8, w, h)
                self._respecified = self._main_cb_ms

        def _read_main_framebuffer(self, scene, flags):
            width, height = self._main_fb_dims[0], self._main_fb_dims[1]
            GL.glBindFramebuffer(GL.GL_READ_FRAMEBUFFER, self._main_fb_ms)
            GL.glBindFramebuffer(GL.GL_DRAW_FRAMEBUFFER, self._main_fb)
            GL.glBlitFramebuffer(0, 0, width, height, 0, 0, width, height, GL.GL_COLOR_BUFFER_BIT, GL.GL_NEAREST)
            GL.glBindFramebuffer(GL.GL_READ_FRAMEBUFFER, self._main_fb)
            GL.glPixelStorei(GL.GL_PACK_ALIGNMENT, 1)
            buf = GL.glReadPixels(0, 0, width, height, GL.GL_RED, GL.GL_UNSIGNED_BYTE)
            return np.frombuffer(buf, dtype=np.uint8).reshape(height, width)[::-1], None

    return _GreyRenderer


def _offscreen(pyrender, renderer_class, width: int, height: int):
    """A pyrender OffscreenRenderer of ``width x height`` drawing with ``renderer_class(width, height)``."""
    renderer = pyrender.OffscreenRenderer(width, height)
    try:
        renderer._renderer.delete()
        renderer._renderer = renderer_class(width, height)
    except Exception:
        _delete_offscreen(renderer)
        raise
    return renderer


class _PinholeRenderer:
    """Camera set-up and life cycle shared by the 3-D renderers (boxes, meshes).

    :meth:`_set_camera` validates and stores the image size, intrinsics, background and
    trajectory; :meth:`_add_camera` puts the matching pyrender camera in a scene; :meth:`close`
    (idempotent; also the context manager's exit) drops the caches (``_drop_caches``) and
    frees the OpenGL context, if one was made.
    """

    _renderer = None
    _closed = False

    def _set_camera(self, width, height, fx, fy, cx, cy, background, trajectory, supersample,
                    odd_supersample: bool = False) -> None:
        for name, value in (("width", width), ("height", height), ("supersample", supersample)):
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
                raise TypeError(f"{name} must be an int, got {type(value).__name__}")
            if value <= 0:
                raise ValueError(f"{name} must be > 0, got {value}")
        if odd_supersample and supersample % 2 == 0:
            raise ValueError(f"supersample must be odd (a sample at the pixel centre), got {supersample}")
        fx, fy, cx, cy = (_finite(v, n) for v, n in ((fx, "fx"), (fy, "fy"), (cx, "cx"), (cy, "cy")))
        if fx <= 0 or fy <= 0:
            raise ValueError(f"fx and fy must be > 0, got fx={fx}, fy={fy}")
        background = _finite(background, "background")
        if not 0.0 <= background <= 1.0:
            raise ValueError(f"background must lie in [0, 1], got {background}")
        if not isinstance(trajectory, _Trajectory):
            raise TypeError(f"trajectory must be a CameraTrajectory or KeyframeTrajectory, got "
                            f"{type(trajectory).__name__}")
        self.width, self.height = int(width), int(height)
        self.fx, self.fy, self.cx, self.cy = fx, fy, cx, cy
        self.background = background
        self.supersample = int(supersample)
        self.trajectory = trajectory
        # Normalised image coordinates of the pixel centres (x = X/Z, y = Y/Z).
        self._x = ((np.arange(self.width, dtype=np.float64) - cx) / fx)[None, :].repeat(self.height, 0)
        self._y = ((np.arange(self.height, dtype=np.float64) - cy) / fy)[:, None].repeat(self.width, 1)

    def _add_camera(self, pyrender, scene) -> None:
        """Add the camera (intrinsics scaled by the supersampling; OpenGL pixel centres) to ``scene``."""
        s = self.supersample
        camera = pyrender.IntrinsicsCamera(fx=s * self.fx, fy=s * self.fy, cx=s * (self.cx + 0.5),
                                           cy=s * (self.cy + 0.5), znear=ZNEAR_M, zfar=ZFAR_M)
        self._camera_node = scene.add(camera, pose=np.eye(4))
        self._scene = scene

    def _draw(self, t_s: float):
        """The colour buffer pyrender draws at ``t_s`` (scene, camera and ``_flags`` set up by
        ``_build_gl`` on first use)."""
        if self._renderer is None:
            self._build_gl()
        self._scene.set_pose(self._camera_node, opencv_to_gl_pose(self.trajectory.pose(t_s)))
        return self._renderer.render(self._scene, flags=self._flags)[0]

    def _drop_caches(self) -> None:
        raise NotImplementedError

    def close(self) -> None:
        """Free the OpenGL context, if one was made (idempotent); the renderer cannot render afterwards."""
        self._closed = True
        self._drop_caches()
        if self._renderer is not None:
            renderer, self._renderer = self._renderer, None
            _delete_offscreen(renderer)

    @property
    def closed(self) -> bool:
        return self._closed

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False
