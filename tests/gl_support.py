"""Skip a test, with the reason, when this machine cannot create an EGL OpenGL context."""

from __future__ import annotations

import pytest


def require_gl() -> None:
    from renderers.gl import GLRenderer, GLUnavailable

    gl = GLRenderer()
    try:
        gl._ensure_context()
    except GLUnavailable as err:
        pytest.skip(f"no EGL OpenGL context on this machine: {err}")
    finally:
        gl.close()
