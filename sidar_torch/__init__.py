"""sidar_torch: SIDAR image sequences (views, occlusion masks, label, homographies) rendered on the fly.

>>> from torch.utils.data import DataLoader
>>> from sidar_torch import SidarDataset, load_config
>>> ds = SidarDataset(source=None, config=load_config("misaligned", image_size=(384, 512)), seed=0)
>>> batch = next(iter(DataLoader(ds, batch_size=8, num_workers=2)))  # doctest: +SKIP

Importing the package loads no GL library (pyrender and PyOpenGL load at the first render), so
configs, ``homography_pairs`` and ``ExportedDataset`` work on machines without them.
"""

from . import render  # noqa: F401  (sets PYOPENGL_PLATFORM, LP_NUM_THREADS before OpenGL's import; loads no GL)
from .config import SidarConfig, available_presets, load_config
from .data.augment import SidarAugment
from .data.augment_step import SidarStep
from .data.dataset import SidarDataset
from .sample.correspondence import flow
from .evaluation.scoring import evaluate
from .io import ExportedDataset, export_dataset
from .sample.lens_views import undistort
from .data.pairs import homography_pairs
from .version import __version__  # noqa: F401  (the package's version, recorded in export manifests)

__all__ = [
    "ExportedDataset", "SidarAugment", "SidarConfig", "SidarDataset", "SidarStep", "available_presets", "evaluate",
    "export_dataset", "flow", "homography_pairs", "load_config", "undistort",
]
