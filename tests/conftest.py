"""Shared test settings: small images keep rendering fast on CPU."""

import numpy as np
import pytest

import sidar_torch  # noqa: F401  (selects the OSMesa platform before anything imports OpenGL)
from sidar_torch import load_config

SMALL = (96, 128)


def small_config(preset="misaligned", **overrides):
    """A preset at 96 x 128 with 3 views, unless overridden."""
    return load_config(preset, **{"image_size": SMALL, "n_views": 3, **overrides})


def textured_painting(size, seed=0):
    """``(H, W, 3)`` uint8 random texture: every pixel differs from its neighbours."""
    return np.random.default_rng(seed).integers(0, 256, (*size, 3), dtype=np.uint8)


@pytest.fixture
def rng():
    return np.random.default_rng(1234)
