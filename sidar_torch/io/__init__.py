"""Export: freeze a :class:`~sidar_torch.SidarDataset` to disk, and read it back.

:func:`export_dataset` writes sequences ``start .. start + count - 1`` of a dataset as one folder
per sequence with the SIDAR paper's file names (the default, :mod:`.folders`: a MATLAB file per
ordered pair of views), in the paper's own layout (``layout="paper"``, :mod:`.paper`: its
``H_i_j.mat`` texts in its pixels, as its generator writes them) or in WebDataset-style tar shards
(:mod:`.shards`); :class:`ExportedDataset` (:mod:`.reader`) loads any of them back into the dict
:meth:`SidarDataset.sample` returns, tensor for tensor byte-identical (the views are 8-bit
renders, so 8-bit PNGs hold them exactly). Each layout is one class answering the same interface
(:class:`.layout.Layout`: which sequences are here, how missing ones group into write units, write
a unit, list the sequences, read an entry), one row of the table :data:`.layouts.LAYOUTS` keyed by
the manifest's ``layout`` name; export, the reader and Ray look it up there and ask it. What the
layouts share: that interface and the top-level names (:mod:`.layout`), a sequence as entries
(:mod:`.entries`) and their bytes (:mod:`.codecs`), atomic writes, the lock and bounded reads
(:mod:`.files`), the manifest (:mod:`.manifest`). What Ray's export (``sidar_torch.io.cluster``) and
the command line use is public here: :class:`ExportPlan` and :func:`planned_export` (what an export
into a prepared folder writes), :class:`Progress`, :class:`~.layout.Layout` and its
:class:`~.layout.WriteUnit`, :data:`LAYOUTS`.

Folder layout (``shard_size=None``)::

    out/
      export.json        format, package version, layout, seed, painting source, config
      config.yaml        the config (``load_config("out/config.yaml")`` gives it back)
      000000/            one folder per sequence (see :mod:`.folders`)

Shard layout (``shard_size=N``): ``shard-00000.tar``, ``shard-00001.tar``, ... beside
``export.json`` and ``config.yaml`` (see :mod:`.shards`).

Homography convention: the package's (Kornia's): pixel ``(u, v)`` is column ``u``, row ``v``, the
centre of the top-left pixel is ``(0, 0)``, and ``H[i, j]`` maps view-i pixels to view-j pixels.
The paper's Blender files use coordinates in which the image's outer edges are ``0`` and
``W - 1`` (``x = (u + 1/2) (W - 1) / W``, likewise for rows), up to half a pixel off the rendered
pixel grid; to compare with them, conjugate: ``H_paper = S H S^-1`` with
``S = [[(W-1)/W, 0, (W-1)/(2W)], [0, (H-1)/H, (H-1)/(2H)], [0, 0, 1]]``.

Safety. Each sequence (or shard, or manifest file) is written into ``out/.tmp-sidar-<name>`` and
moved into place by one ``os.replace``, so a folder ``000007/`` or a ``shard-*.tar`` is either
complete or absent; ``export.json`` is written before ``config.yaml``, so an interruption at any
point (a kill, a full disk, Ctrl-C: :class:`ExportInterrupted`) leaves a folder the same call
resumes. A rerun with the same arguments skips what exists, deletes the ``.tmp-sidar-<name>`` left
by a killed run (and no other file: a folder without ``export.json`` that holds anything else
is refused as not empty), rewrites a damaged (truncated) shard and renders only what is missing;
samples are pure functions of ``(seed, index)``, so the result is byte for byte an uninterrupted
export's. Files are not ``fsync``-ed: this protects against the process dying, not against
losing power. One export at a time may write to a folder (a POSIX lock on ``out/.export.lock``,
which DataLoader workers do not inherit, released when the export's process dies and removed when
it ends), and a rerun must keep the seed, source, config and layout recorded in ``export.json``
(else ``ValueError``).

The reader reads only regular files inside the export folder, of bounded size, and checks every
field of ``export.json`` it uses, its ``image_size`` and ``n_views`` against the package's bounds
(:mod:`.limits`), and each file against them before decoding it (:mod:`.codecs`): a damaged or
tampered export is a ``ValueError`` naming the file, read in bounded memory.
"""

from .entries import pixel_entries_text
from .export import (ExportInterrupted, ExportPlan, ExportSummary, Progress, either_shard_size, export_dataset,
                     planned_export)
from .layout import Layout, WriteUnit
from .layouts import LAYOUTS
from .reader import ExportedDataset

__all__ = ["LAYOUTS", "ExportInterrupted", "ExportPlan", "ExportSummary", "ExportedDataset", "Layout", "Progress",
           "WriteUnit", "either_shard_size", "export_dataset", "pixel_entries_text", "planned_export"]

