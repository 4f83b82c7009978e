"""Named, versioned test sets: what a benchmark renders, pinned so that everyone compares on the same data.

A test set is a JSON file shipped here (``homography-v1.json``, ...): per category (an artifact
kind: ``clean``, ``lights``, ``shadows``, ``occlusions``, ``all``) the full config, the seed and the
number of sequences (indices ``0 .. count-1``); the pairs evaluated (``reference``: view 0 to each
other view); and the SHA-256 digest of every file of its export (the folder layout, one export per
category, ``<category>/<sequence>/<file>``), with the rasteriser (GL renderer and version,
:func:`sidar_torch.render.context.current_rasteriser`) and package versions that recorded them. The data is not shipped:
:func:`export_testset` renders it and checks it against the digests.

A published set is never changed: a change is a new name (``homography-v2``). The test suite holds
the SHA-256 of each shipped definition (``tests/test_testsets.py``).

Pixels come from the rasteriser: on another one (another Mesa release or llvmpipe build, a GPU)
PNG files may differ from the recorded digests, and ``cameras.json`` and the ``.mat`` files may
differ in the last bits of their float64 numbers; :class:`DigestCheck` says which files differ.
The ground truth evaluated is read from the exported files themselves, so an evaluation stays
valid there; only comparisons across machines then compare slightly different pixels.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

from ...config import SidarConfig, load_config
from ...data.dataset import SidarDataset
from ...io import export_dataset
from ...io.layout import SEQUENCE_NAME

__all__ = ["Category", "DigestCheck", "TestSet", "available_testsets", "check_digests", "definition_digest",
           "export_testset", "file_digests", "load_testset"]

PAIRS = ("reference",)
"""The pair sets a definition may name: ``reference``, view 0 to each other view ``(0, j)``."""


@dataclass(frozen=True)
class Category:
    """One category of a test set: an export of ``count`` sequences (indices ``0 .. count-1``).

    Attributes:
        name: its name (``clean``, ``shadows``, ...), also its folder in an export of the set.
        description: what it holds, in words.
        config: every config field (``SidarConfig.to_dict()``), so that a preset's later change
            cannot change the set.
        seed: the dataset seed.
        count: its number of sequences.
    """

    name: str
    description: str
    config: dict[str, Any]
    seed: int
    count: int

    def dataset(self) -> SidarDataset:
        """The :class:`SidarDataset` (built-in procedural paintings) whose samples ``0 .. count-1`` it holds."""
        return SidarDataset(source=None, config=load_config(None, **self.config), seed=self.seed)


@dataclass(frozen=True)
class TestSet:
    """A shipped test set (see the module docstring).

    Attributes:
        name: e.g. ``homography-v1``.
        task: ``homography`` (pairs scored by corner error) or ``shadow-removal`` (views scored
            against their shadow-free targets).
        description: what it is for, in words.
        pairs: which view pairs a homography set scores (:data:`PAIRS`).
        categories: its categories, in the order evaluation interleaves them.
        digests: ``{"<category>/<sequence>/<file>": SHA-256 hex}`` of every sequence file of its export.
        recorded_on: the rasteriser (``SceneRenderer.rasteriser()``; for the v1 sets, whose files name no GL
            version, :data:`V1_GL_VERSION`) and the package versions that recorded ``digests``.
    """

    __test__ = False  # not a pytest class, whatever its name

    name: str
    task: str
    description: str
    pairs: str
    categories: tuple[Category, ...]
    digests: dict[str, str]
    recorded_on: dict[str, str]


def _definitions() -> Any:
    return resources.files(__package__)


def available_testsets() -> list[str]:
    """The names of the shipped test sets, sorted."""
    return sorted(p.name[:-len(".json")] for p in _definitions().iterdir() if p.name.endswith(".json"))


def definition_digest(name: str) -> str:
    """SHA-256 hex of the shipped definition file of test set ``name`` (what the tests hold constant)."""
    return hashlib.sha256(_definition_bytes(name)).hexdigest()


def _definition_bytes(name: str) -> bytes:
    if name not in available_testsets():
        raise ValueError(f"testset: expected one of {available_testsets()} or a folder, got {name!r}")
    return (_definitions() / f"{name}.json").read_bytes()


def load_testset(name: str) -> TestSet:
    """The shipped test set ``name``.

    Raises:
        ValueError: no such set (the message lists the shipped ones).
    """
    data = json.loads(_definition_bytes(name))
    categories = tuple(Category(**category) for category in data["categories"])
    return TestSet(name=data["name"], task=data["task"], description=data["description"], pairs=data["pairs"],
                   categories=categories, digests=data["digests"],
                   recorded_on={"gl_version": V1_GL_VERSION, **data["recorded_on"]})


V1_GL_VERSION = "4.5 (Core Profile) Mesa 22.3.6"
"""The GL version of the sets published before definitions recorded one (the v1 sets, whose files
cannot change): their digests reproduce on Mesa 22.3.6 (``tests/test_testsets.py``); on Mesa 25.0.7
with the same LLVM, 2 of the 52 files that test checks differ."""


def file_digests(out: Path) -> dict[str, str]:
    """``{"<category>/<sequence>/<file>": SHA-256 hex}`` of every file in the sequence folders of
    the category exports under ``out`` (``export.json`` and ``config.yaml`` are left out: they hold
    the package version)."""
    digests = {}
    for path in sorted(out.glob("*/*/*")):
        if path.is_file() and SEQUENCE_NAME.match(path.parent.name):
            digests[path.relative_to(out).as_posix()] = hashlib.sha256(path.read_bytes()).hexdigest()
    return digests


@dataclass(frozen=True)
class DigestCheck:
    """An export of a test set against its recorded digests.

    Attributes:
        checked: how many of its files have a recorded digest and were compared.
        differing: the files whose digest differs, sorted.
        unknown: files written that the definition has no digest for (none for a sound export).
        recorded_on: the rasteriser the digests were recorded on, in words (:func:`rasteriser_name`).
        renderer: the rasteriser that rendered this export, in words (``None`` if none rendered here).
    """

    checked: int
    differing: tuple[str, ...]
    unknown: tuple[str, ...]
    recorded_on: str
    renderer: str | None

    @property
    def matches(self) -> bool:
        """True when every file compared has its recorded digest."""
        return not self.differing and not self.unknown

    def summary(self) -> str:
        """One paragraph: every file matches, or which differ and what that means."""
        if self.matches:
            return f"all {self.checked} files match the recorded SHA-256 digests"
        kinds = sorted({name.rsplit(".", 1)[-1] for name in self.differing})
        text = (f"{len(self.differing)} of {self.checked} files differ from the recorded digests "
                f"({', '.join(kinds)} files; first: {', '.join(self.differing[:3])})")
        if self.unknown:
            text += f"; {len(self.unknown)} files have no recorded digest (first: {self.unknown[0]})"
        here = "an unknown renderer (not rendered by this call)" if self.renderer is None else repr(self.renderer)
        text += (f". The digests were recorded on {self.recorded_on!r}, these files on {here}: pixels "
                 f"may differ between renderers (by how much cannot be known without the reference files, which "
                 f"are not shipped), and float64 geometry in its last bits. The ground truth is read from these "
                 f"files, so `evaluate` on them is valid; its scores compare with others' only approximately")
        return text


def check_digests(testset: TestSet, out: Path, renderer: dict[str, str] | None = None) -> DigestCheck:
    """Compare the sequence files under ``out`` (an export of ``testset``, whole or its first
    sequences) with the recorded digests; ``renderer``: the ``SceneRenderer.rasteriser()`` that rendered them."""
    now = file_digests(out)
    known = [name for name in now if name in testset.digests]
    return DigestCheck(checked=len(known),
                       differing=tuple(name for name in known if now[name] != testset.digests[name]),
                       unknown=tuple(name for name in now if name not in testset.digests),
                       recorded_on=rasteriser_name(testset.recorded_on),
                       renderer=None if renderer is None else rasteriser_name(renderer))


def export_testset(testset: TestSet, out: str | Path, sequences: int | None = None,
                   progress: bool = True) -> DigestCheck:
    """Render test set ``testset`` into ``out`` (one folder-layout export per category, resumable)
    and check its files against the recorded digests.

    Args:
        testset: a :class:`TestSet` (:func:`load_testset`).
        out: the folder; ``out/<category>`` is each category's export.
        sequences: the first this many sequences of each category (``None``: all of them).
        progress: print each export's progress line on stderr.

    Returns:
        The :class:`DigestCheck` of the files under ``out``.
    """
    out = Path(out)
    renderer = None
    for category in testset.categories:
        count = category.count if sequences is None else min(sequences, category.count)
        dataset = category.dataset()
        summary = export_dataset(dataset, out / category.name, count, progress=progress)
        if summary.written:
            renderer = dataset.renderer().rasteriser()
    return check_digests(testset, out, renderer)


def same_rasteriser(recorded: dict[str, str], here: dict[str, str]) -> bool:
    """Whether pixels recorded on ``recorded`` (a ``SceneRenderer.rasteriser()`` record, or the ``recorded_on`` /
    ``recorded_with`` dict holding one) can be compared byte for byte on ``here``: the same GL
    renderer and, where ``recorded`` names one, the same GL version (records older than it name none)."""
    return (recorded.get("gl_renderer") == here["gl_renderer"]
            and recorded.get("gl_version", here["gl_version"]) == here["gl_version"])


def rasteriser_name(record: dict[str, str]) -> str:
    """``record``'s rasteriser in words: its GL renderer, then its GL version or that none was recorded."""
    return f"{record.get('gl_renderer', '(unknown)')}, {record.get('gl_version', 'GL version not recorded')}"


def category_config(preset: str, **overrides: Any) -> dict[str, Any]:
    """Every config field of ``preset`` with ``overrides``: what a definition pins for a category."""
    config: SidarConfig = load_config(preset, **overrides)
    return config.to_dict()
