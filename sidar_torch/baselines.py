"""Baseline estimators for :func:`sidar_torch.evaluate`, by name (:data:`ESTIMATORS`).

A homography estimator maps ``(source, target)``, two ``(H, W, 3)`` uint8 RGB views, to a ``(3, 3)``
float64 homography from source pixels to target pixels (Kornia's and OpenCV's convention: the centre
of the top-left pixel at ``(0, 0)``), or ``None`` when it fails. A shadow-removal estimator maps one
view to its shadow-free version, ``(H, W, 3)`` uint8.

The OpenCV baselines need the ``bench`` extra (``pip install "sidar_torch[bench]"``, OpenCV): without
it they raise an ``ImportError`` that says so. RANSAC is seeded (``cv2.setRNGSeed(0)`` before each
estimate), so scores repeat.
"""

from __future__ import annotations

import importlib
import os
from pathlib import Path
from typing import Any, Callable

import kornia
import numpy as np
import torch
from torch import nn

__all__ = ["ESTIMATORS", "Estimator", "HOMOGRAPHYNET_WEIGHTS", "ecc", "homography_net", "homographynet",
           "identity", "orb_ransac", "resolve_estimator", "sift_magsac", "sift_ransac"]

Estimator = Callable[..., Any]

RATIO = 0.8
"""Lowe's ratio test: a match is kept when its descriptor distance is below this fraction of the
second nearest's (the value of the repository's realism report, ``benchmarks/matcher.py``)."""

RANSAC_PX = 3.0
"""Reprojection threshold (pixels) of RANSAC and of MAGSAC's largest noise scale."""

HOMOGRAPHYNET_WEIGHTS = "SIDAR_TORCH_HOMOGRAPHYNET"
"""Environment variable naming the weights ``examples/train_homography.py --save PATH`` wrote
(default ``~/.cache/sidar_torch/homographynet.pt``)."""


def _cv2() -> Any:
    try:
        import cv2
    except ImportError:
        raise ImportError('the OpenCV baselines (sift, sift-magsac, orb, ecc) need OpenCV: '
                          'pip install "sidar_torch[bench]" (opencv-python-headless)') from None
    return cv2


def _grey(image: np.ndarray) -> np.ndarray:
    return _cv2().cvtColor(np.ascontiguousarray(image), _cv2().COLOR_RGB2GRAY)


def identity(source: np.ndarray, target: np.ndarray | None = None) -> np.ndarray:
    """No motion: the ``(3, 3)`` identity (homography sets); the view itself (shadow removal, one argument)."""
    return np.eye(3) if target is not None else source


def _matched_homography(source: np.ndarray, target: np.ndarray, detector: Any, norm: int,
                        method: int) -> np.ndarray | None:
    """Keypoints of ``detector`` in both views, ratio-test matches (:data:`RATIO`), and
    ``cv2.findHomography`` with ``method`` at :data:`RANSAC_PX`; ``None`` below 4 matches or no estimate."""
    cv2 = _cv2()
    points_a, descriptors_a = detector.detectAndCompute(_grey(source), None)
    points_b, descriptors_b = detector.detectAndCompute(_grey(target), None)
    if descriptors_a is None or descriptors_b is None or len(points_b) < 2:
        return None
    pairs = cv2.BFMatcher(norm).knnMatch(descriptors_a, descriptors_b, k=2)
    kept = [p[0] for p in pairs if len(p) == 2 and p[0].distance < RATIO * p[1].distance]
    if len(kept) < 4:
        return None
    a = np.float32([points_a[m.queryIdx].pt for m in kept])
    b = np.float32([points_b[m.trainIdx].pt for m in kept])
    cv2.setRNGSeed(0)
    H, _ = cv2.findHomography(a, b, method, RANSAC_PX)
    return H


def sift_ransac(source: np.ndarray, target: np.ndarray) -> np.ndarray | None:
    """OpenCV SIFT (default parameters), ratio test, RANSAC (3 px)."""
    cv2 = _cv2()
    return _matched_homography(source, target, cv2.SIFT_create(), cv2.NORM_L2, cv2.RANSAC)


def sift_magsac(source: np.ndarray, target: np.ndarray) -> np.ndarray | None:
    """OpenCV SIFT, ratio test, USAC-MAGSAC++ (``cv2.USAC_MAGSAC``, 3 px)."""
    cv2 = _cv2()
    return _matched_homography(source, target, cv2.SIFT_create(), cv2.NORM_L2, cv2.USAC_MAGSAC)


def orb_ransac(source: np.ndarray, target: np.ndarray) -> np.ndarray | None:
    """OpenCV ORB (5000 features), ratio test on Hamming distances, RANSAC (3 px)."""
    cv2 = _cv2()
    return _matched_homography(source, target, cv2.ORB_create(5000), cv2.NORM_HAMMING, cv2.RANSAC)


def ecc(source: np.ndarray, target: np.ndarray) -> np.ndarray | None:
    """``cv2.findTransformECC`` (``MOTION_HOMOGRAPHY``) from the identity, on grey levels in [0, 1],
    at most 100 iterations, Gaussian pre-filter 5 px; ``None`` when it does not converge."""
    cv2 = _cv2()
    warp = np.eye(3, dtype=np.float32)
    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-6)
    try:
        # ECC finds the warp taking the template's (target's) pixels to the input's (source's) ones.
        _, warp = cv2.findTransformECC(_grey(target).astype(np.float32) / 255, _grey(source).astype(np.float32) / 255,
                                       warp, cv2.MOTION_HOMOGRAPHY, criteria, None, 5)
    except cv2.error:
        return None
    return np.linalg.inv(warp.astype(np.float64))


def homography_net() -> nn.Module:
    """A small HomographyNet (DeTone et al. 2016): four conv-BN-ReLU-pool blocks (8, 16, 32, 64
    channels) and two linear layers, ``(N, 2, 64, 64)`` standardised grey pairs -> ``(N, 8)``, the
    four corners' displacements (TL, TR, BR, BL; x, y) divided by 16 (157k parameters)."""
    layers, channels = [], 2
    for out in (8, 16, 32, 64):
        layers += [nn.Conv2d(channels, out, 3, padding=1), nn.BatchNorm2d(out), nn.ReLU(), nn.MaxPool2d(2)]
        channels = out
    return nn.Sequential(*layers, nn.Flatten(), nn.Linear(64 * 4 * 4, 128), nn.ReLU(), nn.Linear(128, 8))


_NETWORKS: dict[str, nn.Module] = {}


def homographynet(source: np.ndarray, target: np.ndarray) -> np.ndarray:
    """The network of ``examples/train_homography.py --save PATH`` (weights from the environment
    variable :data:`HOMOGRAPHYNET_WEIGHTS`), on both whole views resized to 64 x 64 grey: the
    predicted corner displacements of the 64 x 64 frame, scaled back to the views' pixels.

    Raises:
        FileNotFoundError: no weights there (the message says how to make them).
    """
    path = Path(os.environ.get(HOMOGRAPHYNET_WEIGHTS, Path.home() / ".cache" / "sidar_torch" / "homographynet.pt"))
    if str(path) not in _NETWORKS:
        if not path.is_file():
            raise FileNotFoundError(f"{HOMOGRAPHYNET_WEIGHTS}: no HomographyNet weights at {str(path)!r}; write them "
                                    f"with python examples/train_homography.py --save {path}")
        network = homography_net()
        network.load_state_dict(torch.load(path, map_location="cpu", weights_only=True))
        _NETWORKS[str(path)] = network.eval()
    h, w = source.shape[:2]
    views = torch.from_numpy(np.stack([source, target])).permute(0, 3, 1, 2).float() / 255
    grey = kornia.color.rgb_to_grayscale(nn.functional.interpolate(views, (64, 64), mode="area"))[:, 0]
    grey = (grey - grey.mean((1, 2), keepdim=True)) / (grey.std((1, 2), keepdim=True) + 1e-3)
    with torch.no_grad():
        offsets = _NETWORKS[str(path)](grey[None]).view(4, 2).double() * 16
    corners = torch.tensor([[0.0, 0], [63, 0], [63, 63], [0, 63]], dtype=torch.float64)
    small = kornia.geometry.transform.get_perspective_transform(corners[None], (corners + offsets)[None])[0].numpy()
    # Full-size pixels to 64 x 64 pixels (pixel centres at integers in both): x_s = (x + 1/2) 64 / W - 1/2.
    scale = np.array([[64 / w, 0, 32 / w - 0.5], [0, 64 / h, 32 / h - 0.5], [0, 0, 1]])
    return np.linalg.inv(scale) @ small @ scale


ESTIMATORS: dict[str, tuple[Estimator, str]] = {
    "identity": (identity, "no motion (homography); the view unchanged (shadow removal)"),
    "sift": (sift_ransac, "OpenCV SIFT, ratio test 0.8, RANSAC 3 px"),
    "sift-magsac": (sift_magsac, "OpenCV SIFT, ratio test 0.8, USAC-MAGSAC++ 3 px"),
    "orb": (orb_ransac, "OpenCV ORB (5000 features), ratio test 0.8, RANSAC 3 px"),
    "ecc": (ecc, "cv2.findTransformECC, homography, from the identity"),
    "homographynet": (homographynet, f"small HomographyNet trained by examples/train_homography.py (weights: "
                                     f"${HOMOGRAPHYNET_WEIGHTS})"),
}
"""Baseline name -> (estimator, what it is)."""


def resolve_estimator(spec: str) -> tuple[str, Estimator]:
    """``(name, estimator)`` for a baseline's name (:data:`ESTIMATORS`) or ``"module:function"``
    (``module`` importable, e.g. ``my_package.models:estimate``: a module or package in a folder of
    ``sys.path``, which holds the current directory under ``python -m`` and the folders of ``PYTHONPATH``).

    Raises:
        ValueError: neither (the message lists the baselines), or the function is not callable.
        ImportError: no such module (the message says where it must be), or importing it failed
            (its error, the estimator named).
    """
    if spec in ESTIMATORS:
        return spec, ESTIMATORS[spec][0]
    module_name, sep, function_name = spec.partition(":")
    if not sep or not module_name or not function_name:
        raise ValueError(f"estimator: expected one of {sorted(ESTIMATORS)} or MODULE:FUNCTION, got {spec!r}")
    try:
        function = importlib.import_module(module_name)
    except ModuleNotFoundError as error:
        if error.name is None or not (module_name == error.name or module_name.startswith(f"{error.name}.")):
            raise ImportError(f"estimator {spec!r}: importing {module_name!r} failed: {error}") from error
        raise ImportError(f"estimator {spec!r}: no module named {error.name!r}; MODULE must be importable: a "
                          f"module or package in the current directory ({os.getcwd()}) or in a folder on "
                          f"PYTHONPATH") from None
    for part in function_name.split("."):
        if not hasattr(function, part):
            raise ValueError(f"estimator {spec!r}: module {module_name!r} has no {function_name!r}")
        function = getattr(function, part)
    if not callable(function):
        raise ValueError(f"estimator {spec!r}: expected a callable, got {type(function).__name__}")
    return spec, function
