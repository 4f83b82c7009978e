"""Rendering: pyrender on an offscreen OpenGL context (OSMesa unless told otherwise).

Importing this package fixes two environment variables before anything imports OpenGL:

* ``PYOPENGL_PLATFORM`` (default ``osmesa``, or ``egl``; see ``context``): PyOpenGL reads it once,
  at its first import.
* ``LP_NUM_THREADS`` (default ``0``): llvmpipe then rasterises in the calling thread. A process
  that created a context with llvmpipe's worker threads deadlocks any child it forks at the
  child's first GL call; with no worker threads, forking DataLoader workers is safe even after
  the parent rendered. On 2 cores, one thread per worker process is also the fastest split.

With ``egl``, also ``PYGLET_HEADLESS`` (default ``true``): pyrender's import loads pyglet, which
otherwise needs X11's libraries. Set any of them before importing ``sidar_torch`` to choose otherwise.

Who renders where (:func:`renderer_for`): a process that may fork (a training script's main process)
renders its own samples in a render process it forks (``process``), which keeps Mesa's disk cache on
(shader variants loaded, not compiled: a fresh process's first sample in about half a second); the
process itself opens no context, so the DataLoader workers and render pools it forks open their own,
with the cache. Those workers render in their own process. A context opened in a process that may fork
(a test's or a benchmark's :func:`shared_renderer`) keeps the cache off: a child forked after it would
deadlock at its first cache write.

Importing this package loads no GL library: ``renderer`` (pyrender, PyOpenGL) is imported at the
first use of :func:`shared_renderer` or an attribute named in
``__all__``, after :func:`~.context.check_platform_libraries`, whose error names what to install.
So ``import sidar_torch`` and everything that does not render work without the GL libraries.
"""

import functools
import os

os.environ.setdefault("PYOPENGL_PLATFORM", "osmesa")
os.environ.setdefault("LP_NUM_THREADS", "0")
if os.environ["PYOPENGL_PLATFORM"] == "egl":
    # pyrender's import loads pyglet (for a viewer never opened here), which looks for X11's libraries
    # unless headless: on a GPU server without them (seen on an H100 machine) the import failed.
    # Headless, pyglet uses EGL, which this platform has.
    os.environ.setdefault("PYGLET_HEADLESS", "true")

from .context import may_fork  # noqa: E402  (GL-free)
from .process import RenderProcess  # noqa: E402  (GL-free)
from .settings import RenderSettings  # noqa: E402  (GL-free)

__all__ = ["RenderProcess", "RenderSettings", "RenderedSequence", "SceneRenderer", "preload",
           "render_in_this_process", "renderer_for", "shared_renderer"]


@functools.cache
def _renderer():
    """The ``renderer`` module, imported at the first call once the platform's libraries are found.

    Raises:
        RuntimeError: a GL library is missing (the message names the package to install).
    """
    from .context import check_platform_libraries

    check_platform_libraries()  # before pyrender's import, which fails obscurely without them
    from . import renderer

    return renderer


def preload() -> None:
    """Import the renderer's modules (PyOpenGL, trimesh, pyrender's platform) now, if the GL libraries are there.

    Processes forked afterwards (DataLoader workers, a render pool) inherit them instead of
    importing them at their first render, about 1 s each. It creates no GL context, so forking
    stays safe. Without the libraries it does nothing: the first render raises the error that
    says what to install.
    """
    try:
        _renderer().import_platform()
    except RuntimeError:
        pass


def shared_renderer(settings):
    """:func:`.renderer.shared_renderer` (this process's renderer for ``settings``, a
    :class:`RenderSettings`, in this process), importing the renderer at the first call; defined here so
    that ``from .render import shared_renderer`` loads no GL. Called by :func:`renderer_for` (which the
    owners of a renderer call: ``SidarDataset.renderer``, ``SidarAugment``, the render pool's workers),
    and by tests and benchmarks that measure or inspect the renderer in their own process."""
    return _renderer().shared_renderer(settings)


_PROCESSES: dict[tuple[int, RenderSettings], RenderProcess] = {}
"""The render processes of this process (its pid) by settings: :func:`renderer_for`'s."""

_IN_THIS_PROCESS = False


def render_in_this_process() -> None:
    """Make :func:`renderer_for` hand out this process's own renderer (:func:`shared_renderer`) even where
    the process may fork: for benchmarks, which measure rendering in their own CPU time, and the test
    suite, which inspects renderers. Its contexts keep Mesa's disk cache off, as every context of a process
    that may fork does (``context``), so forking after it rendered stays safe, and each such process
    compiles its shader variants itself."""
    global _IN_THIS_PROCESS
    _IN_THIS_PROCESS = True


def renderer_for(settings):
    """The renderer this process's own samples render with, for ``settings`` (a :class:`RenderSettings`),
    made at the first call and reused; what the owners of a renderer call (``SidarDataset.renderer``,
    ``SidarAugment``, the render pool's workers).

    In a process that may fork (:func:`.context.may_fork`: not a DataLoader or render-pool worker), a
    :class:`~.process.RenderProcess` (a new one if the last died): GL stays out of this process, and the
    render process keeps Mesa's disk cache (see ``process``). Elsewhere, or after
    :func:`render_in_this_process`, :func:`shared_renderer`, in this process. Both have ``render``,
    ``warm_up``, ``rasteriser``, ``settings`` and ``renders``.

    Raises:
        RuntimeError: the platform's GL libraries are missing (the message names the package to install).
    """
    if _IN_THIS_PROCESS or not may_fork():
        return shared_renderer(settings)
    key = (os.getpid(), settings)
    held = _PROCESSES.get(key)
    if held is None or not held.usable:
        from .context import check_platform_libraries

        check_platform_libraries()  # the error that names the package, here rather than in a later GL import
        _PROCESSES[key] = held = RenderProcess(settings, shared_renderer)
    return held


def __getattr__(name):
    if name in ("RenderedSequence", "SceneRenderer"):
        return getattr(_renderer(), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
