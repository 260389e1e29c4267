"""pyrender/EGL plumbing shared by the 3-D renderers: lazy import, single-sample framebuffers, clean deletion.

Importing this module touches no OpenGL; :func:`_import_pyrender` does, setting
``PYOPENGL_PLATFORM=egl`` and ``PYGLET_HEADLESS=1`` first (only if unset).
"""

from __future__ import annotations

import os

import numpy as np

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
