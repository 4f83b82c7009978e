"""Opening the offscreen OpenGL context (OSMesa by default, or EGL), with an error that says what to install.

``PYOPENGL_PLATFORM`` picks the platform (see ``sidar_torch.render``):

* ``osmesa``: Mesa's off-screen library (llvmpipe on the CPU). Mesa 25.1 and later no longer ship it.
* ``egl``: an EGL device from EGL's device enumeration, number ``EGL_DEVICE_ID`` (default 0). On a
  machine without a GPU, Mesa lists one, its software device (llvmpipe, the same rasteriser as
  OSMesa: the pixels are byte-identical); GPU drivers list theirs too (Mesa lists its software
  device first). The context has no default framebuffer: the renderer draws into its own
  (``framebuffer``).
"""

from __future__ import annotations

import ctypes
import os

__all__ = ["GL_PLATFORM", "check_platform_libraries", "open_context"]

GL_PLATFORM = os.environ["PYOPENGL_PLATFORM"]
"""The PyOpenGL platform in use, fixed when ``sidar_torch.render`` was first imported."""

_INSTALL_HINT = {
    "osmesa": "OSMesa (Debian/Ubuntu: apt-get install libosmesa6)",
    "egl": "EGL (Debian/Ubuntu: apt-get install libegl1 libgl1-mesa-dri libopengl0)",
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


def check_platform_libraries() -> None:
    """Raise :func:`open_context`'s error (naming the package to install) if PyOpenGL cannot load
    the platform's shared libraries; called before anything imports pyrender, whose import
    otherwise fails first with an ``AttributeError`` or ``ImportError`` from inside PyOpenGL.

    Raises:
        RuntimeError: a library is missing, or PyOpenGL was imported with another platform.
    """
    from OpenGL import platform

    _check_pyopengl_platform()
    loaded = platform.PLATFORM
    missing = []
    if GL_PLATFORM == "osmesa" and loaded.GL is None:
        missing.append("libOSMesa")
    if GL_PLATFORM == "egl":
        if loaded.EGL is None:
            missing.append("libEGL")
        if loaded.GL in (None, loaded.GLES2, loaded.GLES1):  # PyOpenGL's fallback when neither loads
            missing.append("libOpenGL or libGL")
    if missing:
        raise _cannot_open(f"PyOpenGL cannot load {' and '.join(missing)}")


def _cannot_open(reason: str) -> RuntimeError:
    return RuntimeError(f"cannot open an offscreen OpenGL context on platform {GL_PLATFORM!r} ({reason}); "
                        f"it needs {_INSTALL_HINT.get(GL_PLATFORM, 'osmesa or egl')}")


_FORKS_NOTHING = False


def forks_nothing() -> None:
    """Declare that this process forks no process that renders (a render-pool worker), so its
    first context may keep Mesa's on-disk shader cache, as a DataLoader worker's does (see
    :func:`_disable_disk_cache_unless_worker`)."""
    global _FORKS_NOTHING
    _FORKS_NOTHING = True


def _disable_disk_cache_unless_worker() -> None:
    """Keep Mesa's on-disk shader cache out of processes that may fork.

    The cache writes through a background thread. A child forked after its parent created a
    context inherits the parent's GL screen without that thread, and deadlocks at the first
    draw that compiles a new shader variant. Mesa reads ``MESA_SHADER_CACHE_DISABLE`` when
    the process's first context is created, so it is set here, unless this process is a
    DataLoader worker or declared :func:`forks_nothing` (neither forks) or the user set it. A
    worker forked after its parent rendered inherits the parent's screen, created without the
    cache, and compiles cold.
    """
    from torch.utils.data import get_worker_info

    if get_worker_info() is None and not _FORKS_NOTHING:
        os.environ.setdefault("MESA_SHADER_CACHE_DISABLE", "true")


def _egl_device():
    """The EGL device numbered ``EGL_DEVICE_ID`` (default 0) in EGL's device list.

    Raises:
        ValueError: ``EGL_DEVICE_ID`` is not the number of a listed device.
        OSError: EGL lists no device (no EGL driver installed).
    """
    from pyrender.platforms.egl import query_devices

    text = os.environ.get("EGL_DEVICE_ID", "0")
    try:
        devices = query_devices()
    except RuntimeError as error:  # the driver cannot enumerate devices
        raise OSError(error) from error
    if not devices:
        raise OSError("EGL lists no device")
    if not text.isdigit() or int(text) >= len(devices):
        raise ValueError(f"EGL_DEVICE_ID={text!r}: expected a device number from 0 to {len(devices) - 1} "
                         f"(EGL lists {devices})")
    return devices[int(text)]


def _egl_platform(width: int, height: int):
    """pyrender's EGL platform on :func:`_egl_device`, with a ``delete_context`` that keeps the
    display: EGL has one display per device and process, shared by every renderer on it, and
    pyrender's ``eglTerminate`` there destroys the other renderers' contexts too."""
    from OpenGL import EGL
    from pyrender.platforms.egl import EGLPlatform

    class SharedDisplayEGLPlatform(EGLPlatform):
        def delete_context(self) -> None:
            if self._egl_context is None:
                return
            if _address(EGL.eglGetCurrentContext()) == _address(self._egl_context):
                # A destroyed context that is still current lives on until released.
                EGL.eglMakeCurrent(self._egl_display, EGL.EGL_NO_SURFACE, EGL.EGL_NO_SURFACE, EGL.EGL_NO_CONTEXT)
            EGL.eglDestroyContext(self._egl_display, self._egl_context)
            self._egl_context = None

    return SharedDisplayEGLPlatform(width, height, device=_egl_device())


def _address(handle) -> int | None:
    """The address an EGL handle (a PyOpenGL opaque pointer) points to; None for a null handle."""
    return ctypes.cast(handle, ctypes.c_void_p).value


def import_platform() -> None:
    """Import the platform's module (pyrender's ``platforms``, which loads pyrender, about 1 s) without
    opening a context, so that processes forked afterwards inherit it."""
    if GL_PLATFORM == "osmesa":
        import pyrender.platforms.osmesa  # noqa: F401
    elif GL_PLATFORM == "egl":
        import pyrender.platforms.egl  # noqa: F401


def open_context(width: int, height: int):
    """Create and make current an offscreen context of ``width`` x ``height`` pixels.

    Returns pyrender's platform object (``make_current()``, ``delete_context()``).

    Raises:
        RuntimeError: the platform's library is missing or refuses to create a context; the
            message names the package that provides it.
        ValueError: ``EGL_DEVICE_ID`` names no EGL device.
    """
    _disable_disk_cache_unless_worker()
    try:
        if GL_PLATFORM == "osmesa":
            from pyrender.platforms.osmesa import OSMesaPlatform

            platform = OSMesaPlatform(width, height)
        elif GL_PLATFORM == "egl":
            platform = _egl_platform(width, height)
        else:
            raise RuntimeError(f"PYOPENGL_PLATFORM={GL_PLATFORM!r}: expected 'osmesa' or 'egl'")
        platform.init_context()
        platform.make_current()
    except (ImportError, AttributeError, OSError, AssertionError) as error:
        raise _cannot_open(repr(error)) from error
    return platform
