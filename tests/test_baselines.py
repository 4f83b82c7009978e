"""The baseline estimators (``sidar_torch.evaluation.baselines``) recover a known homography in our pixel
convention; names resolve, wrong ones and a missing OpenCV are errors naming them."""

import sys

import numpy as np
import pytest

from sidar_torch.evaluation import baselines
from sidar_torch.evaluation.baselines import ESTIMATORS, resolve_estimator
from sidar_torch.evaluation.scoring import corner_error
from sidar_torch.paintings import ProceduralPaintings

cv2 = pytest.importorskip("cv2")

SIZE = (240, 320)  # (H, W)
H_TRUE = np.array([[1.02, 0.03, 2.5], [-0.02, 0.99, -1.5], [5e-5, -4e-5, 1.0]])


def textured(size):
    """A built-in procedural painting: features for the matchers, gradients for ECC."""
    return ProceduralPaintings(4).painting(1, size)


@pytest.mark.parametrize("name, px", [("sift", 0.5), ("sift-magsac", 0.5), ("orb", 2.0), ("ecc", 0.5)])
def test_a_baseline_recovers_a_known_homography_in_our_pixels(name, px):
    """Within ``px`` (ORB's keypoints are whole pixels of its pyramid's levels: 0.7-1.1 px on these paintings)."""
    source = textured(SIZE)
    # cv2.warpPerspective maps source pixel x to H x with pixel centres at integers, as ours.
    target = cv2.warpPerspective(source, H_TRUE, SIZE[::-1], flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)
    H = resolve_estimator(name)[1](source, target)
    assert H is not None and corner_error(H, H_TRUE, SIZE) < px


def test_identity_and_a_failure():
    image = textured(SIZE)
    assert (baselines.identity(image, image) == np.eye(3)).all() and baselines.identity(image) is image
    flat = np.zeros((*SIZE, 3), np.uint8)
    assert baselines.sift_ransac(flat, flat) is None  # no keypoints: a failure, not an error


def test_names_resolve_and_wrong_ones_are_errors_naming_them():
    assert resolve_estimator("identity") == ("identity", baselines.identity)
    assert resolve_estimator("sidar_torch.evaluation.baselines:ecc") == ("sidar_torch.evaluation.baselines:ecc", baselines.ecc)
    with pytest.raises(ValueError, match=r"estimator: expected one of \[.*'sidar-net'.*\] or MODULE:FUNCTION"):
        resolve_estimator("sift2")
    with pytest.raises(ValueError, match=r"module 'math' has no 'nope'"):
        resolve_estimator("math:nope")
    with pytest.raises(ValueError, match=r"expected a callable, got float"):
        resolve_estimator("math:pi")
    assert set(ESTIMATORS) == {"identity", "sift", "sift-magsac", "orb", "ecc", "sidar-net", "warp-net"}


@pytest.mark.parametrize("spec, missing", [("no_such_module_here:f", "no_such_module_here"),
                                           ("no_such_package_here.models:f", "no_such_package_here"),
                                           ("sidar_torch.no_such_module:f", "sidar_torch.no_such_module")])
def test_a_module_that_is_not_there_is_an_error_saying_where_it_must_be(spec, missing):
    """Issue 48: ``--estimator myest:orb`` said "No module named 'myest'", nothing about where it is looked for."""
    with pytest.raises(ImportError, match=rf"estimator {spec!r}: no module named {missing!r}; MODULE must be "
                                          r"importable: a module or package in the current directory \(.*\) or in a "
                                          r"folder on PYTHONPATH"):
        resolve_estimator(spec)


def test_a_module_whose_own_import_fails_keeps_its_error_and_names_the_estimator(tmp_path, monkeypatch):
    (tmp_path / "estimator_needing_more.py").write_text("import no_such_dependency_here\n")
    monkeypatch.syspath_prepend(tmp_path)
    with pytest.raises(ImportError, match=r"estimator 'estimator_needing_more:f': importing 'estimator_needing_more' "
                                          r"failed: No module named 'no_such_dependency_here'"):
        resolve_estimator("estimator_needing_more:f")


def test_without_opencv_a_baseline_names_the_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "cv2", None)  # import cv2 raises ImportError
    with pytest.raises(ImportError, match=r'pip install "sidar_torch\[bench\]"'):
        baselines.sift_ransac(np.zeros((8, 8, 3), np.uint8), np.zeros((8, 8, 3), np.uint8))


