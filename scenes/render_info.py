"""Which OpenGL implementation MuJoCo renders with on this machine: Mesa's llvmpipe and an NVIDIA GPU give
different pixels, so the render backend is part of a run's protocol fingerprint."""

from __future__ import annotations

import functools
import os


@functools.cache
def gl_renderer() -> str:
    """``"<GL_VENDOR> / <GL_RENDERER>"`` of a 1x1 context made the way MuJoCo makes its own (``MUJOCO_GL``);
    ``"unavailable: <reason>"`` when no context can be made (the run then renders nothing or fails on its own)."""
    backend = os.environ.get("MUJOCO_GL", "glfw")
    if backend in ("egl", "osmesa"):
        os.environ.setdefault("PYOPENGL_PLATFORM", backend)
    try:
        import mujoco
        from OpenGL import GL

        ctx = mujoco.GLContext(1, 1)
        ctx.make_current()
        try:
            vendor, renderer = (GL.glGetString(x).decode() for x in (GL.GL_VENDOR, GL.GL_RENDERER))
        finally:
            ctx.free()
    except Exception as e:  # no display, no EGL device, no PyOpenGL: say so rather than guess
        return (
            f"unavailable ({backend}): {type(e).__name__}: {str(e).splitlines()[0] if str(e) else ''}".rstrip(
                ": "
            )
        )
    return f"{vendor} / {renderer} ({backend})"
