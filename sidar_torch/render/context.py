"""Opening the offscreen OpenGL context (OSMesa by default), with an error that says what to install."""

from __future__ import annotations

import os

__all__ = ["GL_PLATFORM", "open_context"]

GL_PLATFORM = os.environ["PYOPENGL_PLATFORM"]
"""The PyOpenGL platform in use, fixed when ``sidar_torch.render`` was first imported."""

_INSTALL_HINT = {
    "osmesa": "OSMesa (Debian/Ubuntu: apt-get install libosmesa6)",
    "egl": "EGL (Debian/Ubuntu: apt-get install libegl1 libgl1-mesa-dri)",
}


def _check_pyopengl_platform() -> None:
    """PyOpenGL fixes its platform at its first import: catch an import that came before ours."""
    from OpenGL import platform

    expected = {"osmesa": "OSMesaPlatform", "egl": "EGLPlatform"}.get(GL_PLATFORM)
    if expected and type(platform.PLATFORM).__name__ != expected:
        raise RuntimeError(
            f"PyOpenGL was imported with platform {type(platform.PLATFORM).__name__} before sidar_torch "
            f"could select {GL_PLATFORM!r}: import sidar_torch before OpenGL/pyrender, or set "
            f"PYOPENGL_PLATFORM={GL_PLATFORM} in the environment"
        )


def _disable_disk_cache_unless_worker() -> None:
    """Keep Mesa's on-disk shader cache out of processes that may fork.

    The cache writes through a background thread. A child forked after its parent created a
    context inherits the parent's GL screen without that thread, and deadlocks at the first
    draw that compiles a new shader variant. Mesa reads ``MESA_SHADER_CACHE_DISABLE`` when
    the process's first context is created, so it is set here, unless this process is a
    DataLoader worker (which forks nothing) or the user set it. A worker forked after its
    parent rendered inherits the parent's screen, created without the cache, and compiles cold.
    """
    from torch.utils.data import get_worker_info

    if get_worker_info() is None:
        os.environ.setdefault("MESA_SHADER_CACHE_DISABLE", "true")


def open_context(width: int, height: int):
    """Create and make current an offscreen context of ``width`` x ``height`` pixels.

    Returns pyrender's platform object (``make_current()``, ``delete_context()``).

    Raises:
        RuntimeError: the platform's library is missing or refuses to create a context; the
            message names the package that provides it.
    """
    _check_pyopengl_platform()
    _disable_disk_cache_unless_worker()
    try:
        if GL_PLATFORM == "osmesa":
            from pyrender.platforms.osmesa import OSMesaPlatform

            platform = OSMesaPlatform(width, height)
        elif GL_PLATFORM == "egl":
            from pyrender.platforms.egl import EGLPlatform, get_device_by_index

            platform = EGLPlatform(width, height, device=get_device_by_index(int(os.environ.get("EGL_DEVICE_ID", 0))))
        else:
            raise RuntimeError(f"PYOPENGL_PLATFORM={GL_PLATFORM!r}: expected 'osmesa' or 'egl'")
        platform.init_context()
        platform.make_current()
    except (ImportError, AttributeError, OSError, AssertionError) as error:
        raise RuntimeError(
            f"cannot open an offscreen OpenGL context on platform {GL_PLATFORM!r} ({error!r}); "
            f"it needs {_INSTALL_HINT.get(GL_PLATFORM, 'osmesa or egl')}"
        ) from error
    return platform
