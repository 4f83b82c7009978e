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

__all__ = ["GL_PLATFORM", "EglContext", "check_platform_libraries", "current_rasteriser", "forks_nothing",
           "import_platform", "may_fork", "open_context"]

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
    """Declare that this process forks no process that renders (a render-pool worker, a render process,
    a Ray worker), so it renders in itself and its first context may keep Mesa's on-disk shader cache,
    as a DataLoader worker's does (see :func:`_disable_disk_cache_unless_worker`)."""
    global _FORKS_NOTHING
    _FORKS_NOTHING = True


def may_fork() -> bool:
    """Whether this process may fork a process that renders: not a DataLoader worker, not a daemonic
    ``multiprocessing`` process (a ``Pool`` worker: ``multiprocessing`` refuses it children), not a process
    that declared :func:`forks_nothing` (a render-pool worker, a render process)."""
    import multiprocessing

    from torch.utils.data import get_worker_info

    return get_worker_info() is None and not multiprocessing.current_process().daemon and not _FORKS_NOTHING


def _disable_disk_cache_unless_worker() -> None:
    """Keep Mesa's on-disk shader cache out of processes that may fork (:func:`may_fork`).

    The cache writes through a background thread. A child forked after its parent created a
    context with the cache inherits the parent's GL screen without that thread, and deadlocks at
    the first draw that compiles a new shader variant (Mesa 22.3: the child's
    ``pthread_cond_signal`` on the cache queue's condition variable waits for the parent's thread).
    Mesa reads ``MESA_SHADER_CACHE_DISABLE`` when the process's first context is created, so it is
    set here unless this process forks nothing or the user set it. A process that may fork renders
    its own samples in a render process (``render.process``), which has the cache; a context it
    opens itself (a test's or a benchmark's ``shared_renderer``) compiles cold, and a child forked
    after it inherits that screen, without the cache.
    """
    if may_fork():
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


_EGL_OPENED_BY: int | None = None
"""The process (pid) that initialised an EGL display here, if any: a forked child inherits it."""


def _refuse_inherited_egl() -> None:
    """Refuse EGL in a child forked after its parent initialised an EGL display.

    The child inherits the display's driver state without the driver's threads and device files as
    the parent had them: a new context there hangs at its first draw on Mesa (llvmpipe, measured here)
    and aborts the process in ``eglMakeCurrent`` or ``glReadPixels`` on NVIDIA's driver (580, an H200:
    ``scripts/gpu_check.sh``). Neither can be undone in the child (``eglTerminate`` there hangs too).

    Raises:
        RuntimeError: this process was forked from one that had opened an EGL context.
    """
    if _EGL_OPENED_BY is not None and _EGL_OPENED_BY != os.getpid():
        raise RuntimeError(
            f"this process (pid {os.getpid()}) was forked from process {_EGL_OPENED_BY} after that one opened "
            f"an EGL context, and EGL does not survive a fork (Mesa hangs, NVIDIA's driver aborts): render "
            f"where no EGL context was opened before the fork. By default a process's own samples render in "
            f"a render process (render.renderer_for), which keeps EGL out of the process that forks "
            f"DataLoader workers; after render.render_in_this_process() or a renderer made directly, start "
            f"the workers with DataLoader(..., multiprocessing_context='forkserver') or 'spawn'")


class EglContext:
    """An OpenGL 4.1 core context on an EGL device, without a surface (the renderer draws into its own
    framebuffer), with the methods the renderer calls on a platform (``make_current``, ``delete_context``).

    EGL has one display per device and process, shared by every renderer on it: deleting a context
    keeps the display (``eglTerminate`` there would destroy the other renderers' contexts too).

    Args:
        device: an EGL device of pyrender's ``query_devices`` (its display).

    Raises:
        OSError: EGL refuses to initialise the display, choose a config or create the context.
    """

    def __init__(self, device):
        from OpenGL import EGL, arrays

        global _EGL_OPENED_BY

        # pyrender's platform: an off-screen display, 8-bit RGB and 24-bit depth, OpenGL 4.1 core.
        config_attributes = arrays.GLintArray.asArray([
            EGL.EGL_SURFACE_TYPE, EGL.EGL_PBUFFER_BIT, EGL.EGL_BLUE_SIZE, 8, EGL.EGL_RED_SIZE, 8,
            EGL.EGL_GREEN_SIZE, 8, EGL.EGL_DEPTH_SIZE, 24, EGL.EGL_COLOR_BUFFER_TYPE, EGL.EGL_RGB_BUFFER,
            EGL.EGL_RENDERABLE_TYPE, EGL.EGL_OPENGL_BIT, EGL.EGL_CONFORMANT, EGL.EGL_OPENGL_BIT, EGL.EGL_NONE])
        context_attributes = arrays.GLintArray.asArray([
            EGL.EGL_CONTEXT_MAJOR_VERSION, 4, EGL.EGL_CONTEXT_MINOR_VERSION, 1,
            EGL.EGL_CONTEXT_OPENGL_PROFILE_MASK, EGL.EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT, EGL.EGL_NONE])
        display = os.environ.pop("DISPLAY", None)  # an X display would make EGL pick it
        try:
            self._display = device.get_display()
        finally:
            if display is not None:
                os.environ["DISPLAY"] = display
        major, minor, count = ctypes.c_long(), ctypes.c_long(), ctypes.c_long()
        configs = (EGL.EGLConfig * 1)()
        if not EGL.eglInitialize(self._display, major, minor):
            raise OSError(f"eglInitialize failed on {device}")
        _EGL_OPENED_BY = os.getpid()
        if not EGL.eglChooseConfig(self._display, config_attributes, configs, 1, count) or count.value < 1:
            raise OSError(f"eglChooseConfig found no RGB8, depth-24 OpenGL config on {device}")
        if not EGL.eglBindAPI(EGL.EGL_OPENGL_API):
            raise OSError("eglBindAPI(EGL_OPENGL_API) failed")
        self._context = EGL.eglCreateContext(self._display, configs[0], EGL.EGL_NO_CONTEXT, context_attributes)
        if _address(self._context) is None:
            raise OSError(f"eglCreateContext: no OpenGL 4.1 core context on {device}")

    def make_current(self) -> None:
        from OpenGL import EGL

        if not EGL.eglMakeCurrent(self._display, EGL.EGL_NO_SURFACE, EGL.EGL_NO_SURFACE, self._context):
            raise RuntimeError("eglMakeCurrent failed")

    def delete_context(self) -> None:
        """Destroy the context (once), releasing it first if it is current; keep the display."""
        from OpenGL import EGL

        if self._context is None:
            return
        if _address(EGL.eglGetCurrentContext()) == _address(self._context):
            # A destroyed context that is still current lives on until released.
            EGL.eglMakeCurrent(self._display, EGL.EGL_NO_SURFACE, EGL.EGL_NO_SURFACE, EGL.EGL_NO_CONTEXT)
        EGL.eglDestroyContext(self._display, self._context)
        self._context = None


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

    Returns the platform object (pyrender's ``OSMesaPlatform`` or :class:`EglContext`: ``make_current()``,
    ``delete_context()``).

    Raises:
        RuntimeError: the platform's library is missing or refuses to create a context; the
            message names the package that provides it; or, on EGL, this process was forked after its
            parent opened an EGL context (:func:`_refuse_inherited_egl`).
        ValueError: ``EGL_DEVICE_ID`` names no EGL device.
    """
    _disable_disk_cache_unless_worker()
    try:
        if GL_PLATFORM == "osmesa":
            from pyrender.platforms.osmesa import OSMesaPlatform

            platform = OSMesaPlatform(width, height)
            platform.init_context()
        elif GL_PLATFORM == "egl":
            _refuse_inherited_egl()  # before EGL is touched: its device query may hang in such a child
            platform = EglContext(_egl_device())
        else:
            raise RuntimeError(f"PYOPENGL_PLATFORM={GL_PLATFORM!r}: expected 'osmesa' or 'egl'")
        platform.make_current()
    except (ImportError, AttributeError, OSError, AssertionError) as error:
        raise _cannot_open(repr(error)) from error
    return platform


def current_rasteriser() -> dict[str, str]:
    """What draws the current GL context's pixels: ``{"gl_renderer": GL_RENDERER, "gl_version":
    GL_VERSION}``, e.g. ``"llvmpipe (LLVM 15.0.6, 256 bits)"`` and ``"4.5 (Core Profile) Mesa 22.3.6"``.
    The renderer string names llvmpipe's LLVM and vector width but not Mesa's release, and two releases
    on the same LLVM draw different pixels (Mesa 25.0.7 against 22.3.6: the views of 2 of the 20 samples
    ``tests/stored_digests.py`` records differ). A renderer's own: ``SceneRenderer.rasteriser()``."""
    from OpenGL import GL

    return {"gl_renderer": GL.glGetString(GL.GL_RENDERER).decode(),
            "gl_version": GL.glGetString(GL.GL_VERSION).decode()}
