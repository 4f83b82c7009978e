"""Stream an export's tar shards through the ``webdataset`` package: shards shuffled, samples mixed in
a shuffle buffer, each decoded into sidar_torch's sample dict (the keys, shapes and dtypes of
``SidarDataset``'s samples), batched by a ``DataLoader``.

    pip install webdataset                      # or the package's extra: pip install ".[webdataset]"
    python -m sidar_torch export --out out/shards --count 64 --shard-size 16 --set image_size=[96,128]
    python examples/webdataset_stream.py out/shards
    python examples/webdataset_stream.py --quick   # exports 8 tiny sequences into a temporary folder first

``export --shard-size N`` writes ``shard-00000.tar``, ... whose entries are ``<index>.<file>``
(``000007.0.png``, ``000007.0-m.png``, ``000007.gt.png``, ``000007.cameras.json``,
``000007.homographies.npy``, ...): webdataset groups them by the 6-digit key, so one webdataset
sample holds one sequence's files as bytes, named by what follows the key. :func:`to_sample` decodes
them exactly as ``sidar_torch.ExportedDataset`` does (the same functions, the same checks), so a
streamed sample equals ``ExportedDataset(folder)[k]`` for its sequence, tensor for tensor.

With ``DataLoader(num_workers=n)`` webdataset gives each worker its own shards (have at least as
many shards as workers); across machines pass ``nodesplitter=wds.split_by_node``.
"""

from __future__ import annotations

import argparse
import tempfile
from functools import partial
from pathlib import Path
from typing import Any, Iterable, Iterator, Mapping

import webdataset as wds
from torch.utils.data import DataLoader

from sidar_torch import ExportedDataset, SidarDataset, export_dataset, load_config
from sidar_torch.io.codecs import decode
from sidar_torch.io.entries import sample_from_entries
from sidar_torch.io.shards import HOMOGRAPHIES


def to_sample(entries: Mapping[str, Any], config: Mapping[str, Any]) -> dict[str, Any]:
    """One webdataset sample (``{"__key__": "000007", "0.png": bytes, ...}``) as the sample dict of
    sequence 7, decoded as ``ExportedDataset`` decodes it; ``config``: the export's recorded config
    (``ExportedDataset(folder).config``).

    Raises:
        FileNotFoundError: an entry the config needs is missing (named).
        ValueError: an entry is malformed (named, with the sequence's key).
    """
    key = entries["__key__"]

    def read(name: str, shape: tuple[int, ...] | None = None, check: Any = None) -> Any:
        if name not in entries:
            raise FileNotFoundError(f"{entries.get('__url__', 'shard')}: sequence {key} has no entry {name!r}")
        try:
            value = decode(name, entries[name], shape)
            return value if check is None else check(value)
        except ValueError as error:
            raise ValueError(f"{entries.get('__url__', 'shard')}: entry {key}.{name}: {error}") from None

    arrays = sample_from_entries(read, int(key), config, lambda views: read(HOMOGRAPHIES, (views, views, 3, 3)))
    return arrays.to_tensors(config.get("geometry_dtype", "float32"))


def stream(folder: str | Path, buffer: int = 100, seed: int = 0) -> wds.WebDataset:
    """The shards of the export in ``folder``, shuffled (shard order, then a ``buffer``-sample shuffle
    buffer, both drawn from ``seed``), decoded by :func:`to_sample`: an ``IterableDataset`` of sample dicts."""
    config = ExportedDataset(folder).config  # reads and checks export.json
    urls = sorted(str(path) for path in Path(folder).glob("shard-*.tar"))
    if not urls:
        raise FileNotFoundError(f"{str(folder)!r}: no shard-*.tar (export with --shard-size)")
    return (wds.WebDataset(urls, shardshuffle=len(urls), detshuffle=True, seed=seed, empty_check=False)
            .shuffle(buffer, seed=seed)
            .compose(partial(decoded, config=config)))


def decoded(samples: Iterable[Mapping[str, Any]], config: Mapping[str, Any]) -> Iterator[dict[str, Any]]:
    """:func:`to_sample` of each webdataset sample: a pipeline stage (webdataset's ``.map`` would add
    its ``__key__`` back to each dict; the index is in ``sample["index"]``)."""
    for entries in samples:
        yield to_sample(entries, config)


def main(argv: list[str] | None = None) -> list[list[int]]:
    """Stream the shards once in batches of 4; print and return the dataset indices of each batch."""
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("folder", nargs="?", help="an export written with --shard-size")
    parser.add_argument("--quick", action="store_true", help="export 8 tiny sequences (3 per shard) and stream them")
    parser.add_argument("--buffer", type=int, default=100, help="samples in the shuffle buffer (default 100)")
    args = parser.parse_args(argv)
    if (args.folder is None) == (not args.quick):
        parser.error("give an export folder, or --quick")
    with tempfile.TemporaryDirectory() as scratch:
        folder = args.folder
        if args.quick:
            folder = Path(scratch) / "shards"
            config = load_config("misaligned", image_size=(24, 32), n_views=2, shadow_map_size=256)
            export_dataset(SidarDataset(config=config, seed=0), folder, 8, shard_size=3, progress=False)
        batches = []
        for batch in DataLoader(stream(folder, args.buffer), batch_size=4):
            batches.append(batch["index"].tolist())
            print(f"indices {batches[-1]}: images {tuple(batch['images'].shape)}, "
                  f"homographies {tuple(batch['homographies'].shape)}")
    return batches


if __name__ == "__main__":
    main()
