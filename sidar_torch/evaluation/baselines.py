"""Baseline estimators for :func:`sidar_torch.evaluate`, by name (:data:`ESTIMATORS`).

A homography estimator maps ``(source, target)``, two ``(H, W, 3)`` uint8 RGB views, to a ``(3, 3)``
float64 homography from source pixels to target pixels (Kornia's and OpenCV's convention: the centre
of the top-left pixel at ``(0, 0)``), or ``None`` when it fails. A shadow-removal estimator maps one
view to its shadow-free version, ``(H, W, 3)`` uint8.

The OpenCV baselines need the ``bench`` extra (``pip install "sidar_torch[bench]"``, OpenCV): without
it they raise an ``ImportError`` that says so. RANSAC is seeded (``cv2.setRNGSeed(0)`` before each
estimate), so scores repeat. ``sidar-net`` and ``warp-net`` are the two shipped networks of
:mod:`sidar_torch.deep_homography` (one architecture and budget, trained on sidar_torch pairs and on
classic 2-D warps); they see 128 x 128 pixels (the patch protocol's patches, or whole views resized).
"""

from __future__ import annotations

import importlib
import os
from typing import Any, Callable

import numpy as np

from ..deep_homography.estimators import network_estimator

__all__ = ["ESTIMATORS", "Estimator", "ecc", "identity", "orb_ransac", "resolve_estimator", "sift_magsac",
           "sift_ransac"]

Estimator = Callable[..., Any]

RATIO = 0.8
"""Lowe's ratio test: a match is kept when its descriptor distance is below this fraction of the
second nearest's (the value of the repository's realism report, ``benchmarks/matcher.py``)."""

RANSAC_PX = 3.0
"""Reprojection threshold (pixels) of RANSAC and of MAGSAC's largest noise scale."""


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


ESTIMATORS: dict[str, tuple[Estimator, str]] = {
    "identity": (identity, "no motion (homography); the view unchanged (shadow removal)"),
    "sift": (sift_ransac, "OpenCV SIFT, ratio test 0.8, RANSAC 3 px"),
    "sift-magsac": (sift_magsac, "OpenCV SIFT, ratio test 0.8, USAC-MAGSAC++ 3 px"),
    "orb": (orb_ransac, "OpenCV ORB (5000 features), ratio test 0.8, RANSAC 3 px"),
    "ecc": (ecc, "cv2.findTransformECC, homography, from the identity"),
    "sidar-net": (network_estimator("sidar-net"), "CornerNet trained on sidar_torch pairs (benchmarks.transfer; "
                                                  "weights shipped)"),
    "warp-net": (network_estimator("warp-net"), "CornerNet trained on classic 2-D warps of the same paintings, same "
                                                "budget (weights shipped)"),
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
