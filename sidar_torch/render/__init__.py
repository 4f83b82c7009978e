"""Rendering backend: pyrender on an offscreen OpenGL context (OSMesa unless told otherwise).

Importing this package fixes two environment variables before anything imports OpenGL:

* ``PYOPENGL_PLATFORM`` (default ``osmesa``, or ``egl``; see ``context``): PyOpenGL reads it once,
  at its first import.
* ``LP_NUM_THREADS`` (default ``0``): llvmpipe then rasterises in the calling thread. A process
  that created a context with llvmpipe's worker threads deadlocks any child it forks at the
  child's first GL call; with no worker threads, forking DataLoader workers is safe even after
  the parent rendered. On 2 cores, one thread per worker process is also the fastest split.

Set either variable before importing ``sidar_torch`` to choose otherwise.
"""

import os

os.environ.setdefault("PYOPENGL_PLATFORM", "osmesa")
os.environ.setdefault("LP_NUM_THREADS", "0")

from .context import check_platform_libraries  # noqa: E402  (after the environment is set)

check_platform_libraries()  # before pyrender's import, which fails obscurely without them

from .renderer import RenderedSequence, SceneRenderer, shared_renderer  # noqa: E402
from .settings import RenderSettings  # noqa: E402

__all__ = ["RenderSettings", "RenderedSequence", "SceneRenderer", "shared_renderer"]
