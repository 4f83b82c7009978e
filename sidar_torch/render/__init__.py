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

from .settings import RenderSettings  # noqa: E402  (GL-free)

__all__ = ["RenderSettings", "RenderedSequence", "SceneRenderer", "preload", "shared_renderer"]


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
    :class:`RenderSettings`), importing the renderer at the first call; defined here so that
    ``from .render import shared_renderer`` loads no GL. Called by the owners of a renderer
    (``SidarDataset.renderer``, ``SidarAugment``, the render pool's workers, tests and benchmarks), which
    hand it to what renders (``sidar_torch.sample.render_arrays``)."""
    return _renderer().shared_renderer(settings)


def __getattr__(name):
    if name in ("RenderedSequence", "SceneRenderer"):
        return getattr(_renderer(), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
