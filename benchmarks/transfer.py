"""Does the data teach? One network, one budget, two data arms.

    python -m benchmarks.transfer train [--steps N] [--sequences S] [--presets P ...] [--normalisation N]
        [--paper DIR] [--out out/transfer]
    python -m benchmarks.transfer record [--normalisation N] [--out out/transfer]
    python -m benchmarks.transfer table [--paper DIR] [--chosen-on N] [--out out/transfer]
    python -m benchmarks.transfer diagnose --paper DIR [--out out/transfer]

``train`` renders the training sequences once (``misaligned`` by default, or S of each of several
presets, 384 x 512, 6 views, procedural paintings 1000 .. 1000 + S - 1, seed 0; kept in ``OUT``), then trains the same
:class:`sidar_torch.deep_homography.network.CornerNet` with the same settings twice: on protocol
pairs of those sequences (``sidar-net``) and on the classic 2-D recipe on the same paintings
(``warp-net``). Progress, wall and CPU time are printed; checkpoints in ``OUT`` make it resumable
(run the same command again). Each arm ends with its score on held-out data of both kinds (24
sequences of paintings 5000-5023 of each preset; the first 24 of ``warps-v1``; with ``--paper DIR``, the
first ``--chosen-on`` sequences of a folder in the paper's layout), beside the identity's, and its weights
in ``OUT``.

``record`` copies the two networks' weights from ``OUT`` into the package
(``sidar_torch/deep_homography/weights/``) with what the shipped-weights test checks: each network's
corner offsets on the first protocol pairs of ``warps-v1`` (``scores.json``).

``table`` scores the shipped ``sidar-net`` and ``warp-net``, SIFT + RANSAC and the identity with the
patch protocol (128 px, rho 32, seed 0) on ``warps-v1``, ``homography-v1`` (rendered into
``OUT/homography-v1``) and, with ``--paper DIR``, a folder in the SIDAR paper's layout, and prints a
markdown table: MACE with its 90 % bootstrap interval over pairs (2000 resamples, seed 0), the median
and success rates, and the paired bootstrap interval of sidar-net's MACE over warp-net's; with ``--paper``,
also each estimator's MACE on each of the paper's sequences, and on the first ``--chosen-on`` (those
a recipe was chosen on) and the others apart.

``diagnose --paper DIR`` says why the paper's pairs are hard: how much of their patches is blown out
or black beside ``homography-v1`` and the two presets' held-out pairs, whether the folder's ``H`` puts
the target on the source (the best gradient match of the pairs at rho 0), how often SIFT finds no
homography with no perturbation at all, the shipped networks with twice their refinement rounds (on the
paper's first ``--chosen-on`` sequences and 24 of ``warps-v1``), and on the classic 2-D recipe applied to
the paper's own source photographs (``seqNN/source.png``: the content alone, without the renders).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import shutil
import subprocess
import time
from pathlib import Path

import numpy as np
import torch
from torch.utils.data import DataLoader, Dataset

from sidar_torch import SidarDataset, evaluate, load_config
from sidar_torch.deep_homography import estimators
from sidar_torch.deep_homography.protocol import cut_pair, draw_pairs
from sidar_torch.deep_homography.training import SidarPairs, TrainSettings, WarpPairs, protocol_errors, train
from sidar_torch.deep_homography.warps import WarpTestSet
from sidar_torch.paintings import ProceduralPaintings

PRESETS = ("misaligned",)
"""The sidar arm's presets, the same number of sequences of each (see docs/benchmarks.md for the choice)."""
IMAGE_SIZE = (384, 512)
TRAIN_FIRST = 1000
HELD_OUT_FIRST = 5000


class _Sequences(Dataset):
    """Sequences ``first .. first + count - 1`` of ``preset`` (6 views, :data:`IMAGE_SIZE`) as 8-bit views and masks."""

    def __init__(self, preset: str, first: int, count: int):
        config = load_config(preset, image_size=IMAGE_SIZE, n_views=6)
        self.dataset = SidarDataset(source=None, config=config, seed=0)
        self.first, self.count = first, count

    def __len__(self) -> int:
        return self.count

    def __getitem__(self, k: int) -> dict[str, torch.Tensor]:
        sample = self.dataset.sample(self.first + k)
        return {"images": (sample["images"] * 255).round().to(torch.uint8),
                "masks": sample["masks"].to(torch.uint8), "homographies": sample["homographies"].double()}


def render(preset: str, first: int, count: int, path: Path) -> dict[str, torch.Tensor]:
    """The sequences (see :class:`_Sequences`), rendered by 2 DataLoader workers once and kept at ``path``."""
    if path.is_file():
        return torch.load(path, weights_only=True, mmap=True)
    start = time.perf_counter()
    parts: dict[str, list[torch.Tensor]] = {"images": [], "masks": [], "homographies": []}
    for k, batch in enumerate(DataLoader(_Sequences(preset, first, count), batch_size=8, num_workers=2)):
        for key in parts:
            parts[key].append(batch[key])
        print(f"  rendered {min((k + 1) * 8, count)} / {count} sequences, {time.perf_counter() - start:.0f} s",
              flush=True)
    sequences = {key: torch.cat(value) for key, value in parts.items()}
    torch.save(sequences, path)
    return sequences


def paintings(first: int, count: int) -> torch.Tensor:
    """``(count, 3, H, W)`` uint8: the procedural paintings ``first ..`` at :data:`IMAGE_SIZE`."""
    source = ProceduralPaintings()
    return torch.stack([torch.from_numpy(source.painting(first + k, IMAGE_SIZE)).permute(2, 0, 1)
                        for k in range(count)])


class _Indexed:
    """``dict`` of stacked tensors -> an indexable of per-sequence dicts."""

    def __init__(self, stacked: dict[str, torch.Tensor]):
        self.stacked = stacked

    def __len__(self) -> int:
        return len(self.stacked["images"])

    def __getitem__(self, k: int) -> dict[str, torch.Tensor]:
        return {key: value[k] for key, value in self.stacked.items()}


def _train(args: argparse.Namespace) -> None:
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    torch.set_num_threads(args.threads)
    wall, cpu = time.perf_counter(), time.process_time()
    print(f"rendering {args.sequences} training and 24 held-out sequences of each of {', '.join(args.presets)} "
          f"({IMAGE_SIZE[0]}x{IMAGE_SIZE[1]})", flush=True)
    parts = [render(preset, TRAIN_FIRST, args.sequences, out / f"sequences-{preset}-{args.sequences}.pt")
             for preset in args.presets]
    sequences = {key: torch.cat([part[key] for part in parts]) if len(parts) > 1 else parts[0][key] for key in parts[0]}
    held_out = {f"{preset} held-out": _Indexed(render(preset, HELD_OUT_FIRST, 24, out / f"held-out-{preset}.pt"))
                for preset in args.presets}
    print(f"rendered in {time.perf_counter() - wall:.0f} s wall (this process's CPU {time.process_time() - cpu:.0f} s; "
          f"the workers' is not counted)", flush=True)
    settings = TrainSettings(steps=args.steps, batch=args.batch, seed=args.seed, normalisation=args.normalisation)
    arms = {"sidar-net": SidarPairs(sequences["images"], sequences["masks"], sequences["homographies"]),
            "warp-net": WarpPairs(paintings(TRAIN_FIRST, args.sequences))}
    warps = WarpTestSet(count=24)
    scored = {**held_out, "warps-v1 (24)": warps}
    if args.paper:
        from sidar_torch import ExportedDataset

        paper = ExportedDataset(Path(args.paper), geometry_dtype="float64")
        scored[f"the paper's first {args.chosen_on} sequences"] = [paper[k] for k in range(args.chosen_on)]
    identity = {label: protocol_errors(None, data) for label, data in scored.items()}
    for name in args.arms:
        wall, cpu = time.perf_counter(), time.process_time()

        def report(step: int, loss: float, seconds: float) -> None:
            print(f"  {name}: step {step} / {settings.steps}, loss {loss:.2f} px, {seconds:.0f} s training "
                  f"(this run: {time.perf_counter() - wall:.0f} s wall, {time.process_time() - cpu:.0f} s CPU)",
                  flush=True)

        print(f"training {name}: {settings}", flush=True)
        network = train(arms[name], settings, out / f"{name}.ckpt", report)
        torch.save(network.state_dict(), out / f"{name}.pt")
        for label, data in scored.items():
            errors = protocol_errors(network, data)
            print(f"  {name} on {label}: MACE {errors.mean():.2f} px (identity {identity[label].mean():.2f}), "
                  f"median {np.median(errors):.2f}, {len(errors)} pairs", flush=True)


RECORDED_PAIRS = 4
"""How many protocol pairs of ``warps-v1`` the shipped-weights test replays."""


def recorded_offsets(name: str) -> list[list[list[float]]]:
    """The shipped network ``name``'s corner offsets (pixels, ``(4, 2)`` each) on the first
    :data:`RECORDED_PAIRS` protocol pairs of ``warps-v1`` (seed 0, 128 px, rho 32)."""
    data, found = WarpTestSet(), []
    network = estimators.load_network(name)
    for k in range(len(data)):
        for pair in draw_pairs(data[k], k):
            cut = cut_pair(data[k]["images"], np.eye(3), pair)
            with torch.no_grad():
                found.append(network(cut["source"][None], cut["target"][None])[-1, 0].double().tolist())
            if len(found) == RECORDED_PAIRS:
                return found
    return found


def _record(args: argparse.Namespace) -> None:
    from sidar_torch.deep_homography.network import CornerNet

    folder = Path(estimators.__file__).parent / "weights"
    folder.mkdir(exist_ok=True)
    commit = subprocess.run(["git", "rev-parse", "HEAD"], capture_output=True, text=True).stdout.strip()
    CornerNet(normalisation=args.normalisation)  # a known name, or the error naming them
    record = {"recorded_pairs": RECORDED_PAIRS,
              "networks": {name: {"normalisation": args.normalisation} for name in estimators.NETWORKS}}
    (folder / "scores.json").write_text(json.dumps(record, indent=1) + "\n")  # what load_network reads
    for name, file in estimators.NETWORKS.items():
        shutil.copyfile(Path(args.out) / file, folder / file)
        estimators.load_network.cache_clear()
        record["networks"][name].update(sha256=hashlib.sha256((folder / file).read_bytes()).hexdigest(),
                                        offsets=recorded_offsets(name))
        print(f"{name}: {folder / file}, SHA-256 {record['networks'][name]['sha256']}")
    (folder / "scores.json").write_text(json.dumps(record, indent=1) + "\n")
    print(f"wrote {folder / 'scores.json'} (recorded at commit {commit or 'unknown'})")


def bootstrap(values: np.ndarray, statistic, resamples: int = 2000, seed: int = 0) -> tuple[float, float]:
    """The 5-95 % percentile interval of ``statistic(values[sample])`` over bootstrap resamples of the
    rows of ``values`` (pairs; several columns resample together, for paired statistics)."""
    rng = np.random.default_rng(seed)
    picks = rng.integers(0, len(values), (resamples, len(values)))
    found = np.array([statistic(values[pick]) for pick in picks])
    return float(np.percentile(found, 5)), float(np.percentile(found, 95))


TABLE_ESTIMATORS = ("sidar-net", "warp-net", "sift", "identity")


def _scored(name: str, label: str, testset: str, out: Path) -> dict:
    """``evaluate``'s result for one row, kept in ``OUT/table/`` and reused while the estimator is the same
    (for a network: the same weights, by SHA-256), so a stopped table resumes."""
    version = estimators.weights_sha256(name)[:16] if name in estimators.NETWORKS else "-"
    path = out / "table" / f"{label}-{name}-{version}.json".replace(" ", "_").replace("'", "")
    if path.is_file():
        return json.loads(path.read_text())
    result = evaluate(name, testset, protocol="patches", progress=True,
                      cache=out / "homography-v1" if testset == "homography-v1" else None)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(result))
    return result


def _table(args: argparse.Namespace) -> None:
    sets = {"warps-v1": "warps-v1", "homography-v1": "homography-v1"}
    if args.paper:
        sets["paper's sequences"] = args.paper
    lines = ["| set | estimator | pairs | MACE (90 % interval) | median | <= 3 px | <= 10 px | failures |",
             "|---|---|---|---|---|---|---|---|"]
    ratios = []
    for label, testset in sets.items():
        errors = {}
        for name in TABLE_ESTIMATORS:
            wall = time.perf_counter()
            result = _scored(name, label, testset, Path(args.out))
            errors[name] = np.array(result["pair_errors"])
            low, high = bootstrap(errors[name], np.mean)
            lines.append(f"| {label} | {name} | {result['pairs']} | {result['mace']:.2f} ({low:.2f}-{high:.2f}) | "
                         f"{result['median_error']:.2f} | {100 * result['success']['3']:.0f} % | "
                         f"{100 * result['success']['10']:.0f} % | {result['failures']} |")
            print(lines[-1], f"({time.perf_counter() - wall:.0f} s)", flush=True)
        paired = np.stack([errors["sidar-net"], errors["warp-net"]], 1)
        ratio = paired[:, 0].mean() / paired[:, 1].mean()
        low, high = bootstrap(paired, lambda rows: rows[:, 0].mean() / rows[:, 1].mean())
        ratios.append(f"| {label} | {ratio:.3f} ({low:.3f}-{high:.3f}) |")
    print("\n".join(["", *lines, "", "| set | sidar-net MACE / warp-net MACE (paired 90 % interval) |", "|---|---|",
                     *ratios]))
    if args.paper:
        print("\n".join(["", *_by_sequence(args.paper, args.chosen_on, Path(args.out))]))


def paper_pair_sequences(folder: str | Path) -> np.ndarray:
    """The sequence index of each patch-protocol pair (seed 0, 128 px, rho 32) of a folder in the paper's
    layout, in ``evaluate``'s order (its sequences in name order, each one's pairs in view-pair order)."""
    from sidar_torch import ExportedDataset

    data = ExportedDataset(Path(folder), geometry_dtype="float64")
    return np.array([k for k in range(len(data)) for _ in draw_pairs(data[k], k)])


def _by_sequence(paper: str, chosen_on: int, out: Path) -> list[str]:
    """MACE of each table estimator on each of the paper's sequences, and on the first ``chosen_on`` (used to
    choose the recipe) and the others (not used) apart, with the interval over their pairs."""
    sequences = paper_pair_sequences(paper)
    errors = {name: np.array(_scored(name, "paper's sequences", paper, out)["pair_errors"])
              for name in TABLE_ESTIMATORS}
    if any(len(e) != len(sequences) for e in errors.values()):
        raise ValueError(f"{paper}: the pairs scored are not the protocol's pairs of its sequences (stale table files?)")
    groups = {f"sequence {k + 1}": sequences == k for k in range(int(sequences.max()) + 1)}
    groups[f"sequences 1-{chosen_on} (used to choose the recipe)"] = sequences < chosen_on
    groups[f"sequences {chosen_on + 1}-{int(sequences.max()) + 1} (not used to choose it)"] = sequences >= chosen_on
    lines = ["| paper's sequences | pairs | " + " | ".join(f"{name} MACE" for name in TABLE_ESTIMATORS) + " |",
             "|---|---|" + "---|" * len(TABLE_ESTIMATORS)]
    for label, rows in groups.items():
        cells = []
        for name in TABLE_ESTIMATORS:
            low, high = bootstrap(errors[name][rows], np.mean)
            cells.append(f"{errors[name][rows].mean():.2f} ({low:.2f}-{high:.2f})")
        lines.append(f"| {label} | {int(rows.sum())} | " + " | ".join(cells) + " |")
    return lines


SATURATED, BLACK = 0.97, 0.03
"""Grey levels (in [0, 1]) above which a pixel counts as blown out, below which as black (``diagnose``)."""


def _as_float(sample: dict) -> dict:
    images = sample["images"]
    return dict(sample, images=images.float() / 255 if images.dtype == torch.uint8 else images,
                masks=sample["masks"].float())


def _cut_pairs(sequences, rho: float = 32):
    """``(pair, cut)`` for every protocol pair (seed 0, 128 px) of ``sequences`` (an indexable of samples)."""
    for k in range(len(sequences)):
        sample = _as_float(sequences[k])
        for pair in draw_pairs(sample, k, rho=rho):
            yield pair, cut_pair(sample["images"], sample["homographies"][pair.source, pair.target].double().numpy(),
                                 pair)


def patch_statistics(sequences) -> np.ndarray:
    """``(pairs, 2, 3)``: for the source and target patch of each protocol pair of ``sequences``, the standard
    deviation of its grey levels and the fractions of its pixels above :data:`SATURATED` and below :data:`BLACK`."""
    found = []
    for _, cut in _cut_pairs(sequences):
        grey = torch.stack([cut["source"], cut["target"]]).mul(torch.tensor([0.299, 0.587, 0.114])[:, None, None]).sum(1)
        found.append([[float(g.std()), float((g > SATURATED).double().mean()), float((g < BLACK).double().mean())]
                      for g in grey])
    return np.array(found)


def _gradient(patch: torch.Tensor) -> torch.Tensor:
    grey = patch.mul(torch.tensor([0.299, 0.587, 0.114])[:, None, None]).sum(0)
    grey = torch.nn.functional.avg_pool2d(grey[None, None], 3, 1, 1)[0, 0]
    return torch.hypot(grey[1:-1, 2:] - grey[1:-1, :-2], grey[2:, 1:-1] - grey[:-2, 1:-1])


def best_shifts(sequences, reach: int = 6) -> np.ndarray:
    """``(pairs, 3)``: for every pair of the protocol at ``rho = 0`` (the target should then sit exactly on the
    source), the whole-pixel shift ``(du, dv)`` of the target's gradient magnitude that best correlates with
    the source's within ``reach`` pixels, and that best normalised correlation."""
    found = []
    for _, cut in _cut_pairs(sequences, rho=0):
        a, b = _gradient(cut["source"]), _gradient(cut["target"])
        centre = a[reach:-reach, reach:-reach]
        centre = (centre - centre.mean()) / (centre.std() + 1e-9)
        best = (-2.0, 0, 0)
        size = centre.shape[0]
        for dv in range(-reach, reach + 1):
            for du in range(-reach, reach + 1):
                moved = b[reach + dv:reach + dv + size, reach + du:reach + du + size]
                score = float((centre * (moved - moved.mean()) / (moved.std() + 1e-9)).mean())
                best = max(best, (score, du, dv))
        found.append([best[1], best[2], best[0]])
    return np.array(found)


def _exports(folder: Path) -> list:
    from sidar_torch import ExportedDataset

    return [ExportedDataset(p, geometry_dtype="float64") for p in sorted(folder.iterdir()) if (p / "export.json").is_file()]


class _Chained:
    """Several indexables of samples as one."""

    def __init__(self, parts: list):
        self.items = [(part, k) for part in parts for k in range(len(part))]

    def __len__(self) -> int:
        return len(self.items)

    def __getitem__(self, k: int) -> dict:
        part, index = self.items[k]
        return part[index]


def photo_warps(paper: Path, draws: int = 4) -> list[dict]:
    """The classic 2-D recipe on the paper's own source photographs (``seqNN/source.png``, what its renders
    show): ``draws`` jittered two-view sequences of each (jitter ``default_rng([777, draw, k])``), 8-bit levels."""
    from PIL import Image

    from sidar_torch.deep_homography.warps import classic_sequence

    found = []
    for draw in range(draws):
        for k, path in enumerate(sorted(paper.glob("*/source.png"))):
            image = torch.from_numpy(np.asarray(Image.open(path).convert("RGB")).copy()).permute(2, 0, 1).float() / 255
            sequence = classic_sequence(image, np.random.default_rng([777, draw, k]))
            sequence["images"] = (sequence["images"] * 255).round() / 255
            found.append(sequence)
    return found


def _diagnose(args: argparse.Namespace) -> None:
    """Why the paper's pairs are hard: their patches' light, the truth's check, SIFT with no perturbation,
    the networks with twice the refinement rounds, and on classic warps of the paper's own photographs."""
    import copy

    from sidar_torch import ExportedDataset

    torch.set_num_threads(args.threads)
    out, paper = Path(args.out), Path(args.paper)
    sets = {"paper's sequences": ExportedDataset(paper, geometry_dtype="float64")}
    if (out / "homography-v1").is_dir():
        sets["homography-v1"] = _Chained(_exports(out / "homography-v1"))
    for preset in ("misaligned", "paper_misaligned"):
        sets[f"{preset}, 24 held-out"] = _Indexed(render(preset, HELD_OUT_FIRST, 24, out / f"held-out-{preset}.pt"))
    print(f"| set | pairs | median grey std of a patch | pairs with a patch > 30 % blown out (> {SATURATED}) | "
          f"> 10 % | pairs with a patch > 30 % black (< {BLACK}) |\n|---|---|---|---|---|---|")
    for label, data in sets.items():
        found = patch_statistics(data)
        worst = found.max(1)
        print(f"| {label} | {len(found)} | {np.median(found[:, :, 0]):.3f} | {100 * (worst[:, 1] > 0.3).mean():.0f} % | "
              f"{100 * (worst[:, 1] > 0.1).mean():.0f} % | {100 * (worst[:, 2] > 0.3).mean():.0f} % |", flush=True)
    shifts = best_shifts(sets["paper's sequences"])
    clear = shifts[:, 2] > 0.3
    print(f"\nthe truth's check, paper's sequences at rho 0: {len(shifts)} pairs, {int(clear.sum())} with a clear "
          f"gradient match (best correlation > 0.3); of those, {int((np.abs(shifts[clear, :2]).max(1) <= 1).sum())} "
          f"have it within 1 px of the folder's H (median shift {np.median(np.abs(shifts[clear, :2]).max(1)):.0f} px)")
    for label, testset in (("paper's sequences", paper), ("homography-v1", "homography-v1")):
        result = evaluate("sift", testset, protocol="patches", rho=0,
                          cache=out / "homography-v1" if testset == "homography-v1" else None)
        print(f"SIFT + RANSAC at rho 0 on {label}: no homography found on {result['failures']} of {result['pairs']} "
              f"pairs ({100 * result['failures'] / result['pairs']:.0f} %)", flush=True)
    first = [sets["paper's sequences"][k] for k in range(args.chosen_on)]
    for name in estimators.NETWORKS:
        network = copy.deepcopy(estimators.load_network(name))
        for rounds in (network.iterations, 2 * network.iterations):
            network.iterations = rounds
            print(f"{name} with {rounds} refinement rounds: MACE {protocol_errors(network, first).mean():.2f} px on the "
                  f"paper's first {args.chosen_on} sequences, {protocol_errors(network, WarpTestSet(count=24)).mean():.2f} "
                  f"on warps-v1 (24)", flush=True)
    warps = photo_warps(paper)
    for name in (*estimators.NETWORKS, None):
        errors = protocol_errors(estimators.load_network(name) if name else None, warps)
        print(f"classic warps of the paper's {len(warps) // 4} source photographs, {name or 'identity'}: "
              f"MACE {errors.mean():.2f} px, median {np.median(errors):.2f}, {len(errors)} pairs", flush=True)


def build_parser() -> argparse.ArgumentParser:
    """The command line: ``train``, ``record`` and ``table`` (see the module docstring)."""
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    commands = parser.add_subparsers(dest="command", required=True)
    training = commands.add_parser("train", help="render, train both arms, score them on held-out data")
    training.add_argument("--steps", type=int, default=1500)
    training.add_argument("--batch", type=int, default=32)
    training.add_argument("--sequences", type=int, default=400)
    training.add_argument("--presets", nargs="+", default=list(PRESETS),
                          help=f"the sidar arm's presets, --sequences of each (default {' '.join(PRESETS)})")
    training.add_argument("--seed", type=int, default=0)
    training.add_argument("--normalisation", default="local_contrast", choices=["local_contrast", "standardised"],
                          help="the network's input, both arms (default local_contrast; standardised: version 1's)")
    training.add_argument("--threads", type=int, default=os.cpu_count() or 1)
    training.add_argument("--arms", nargs="+", default=["sidar-net", "warp-net"], choices=["sidar-net", "warp-net"])
    training.add_argument("--out", default="out/transfer")
    training.add_argument("--paper", metavar="DIR", help="also score on a folder in the SIDAR paper's layout ...")
    training.add_argument("--chosen-on", type=int, default=3, metavar="N", help="... its first N sequences (default 3)")
    recording = commands.add_parser("record", help="copy the trained weights into the package, with their answers")
    recording.add_argument("--out", default="out/transfer")
    recording.add_argument("--normalisation", default="local_contrast", choices=["local_contrast", "standardised"],
                           help="the input the networks were trained with (train's --normalisation)")
    table = commands.add_parser("table", help="score the shipped networks, SIFT and the identity (patch protocol)")
    table.add_argument("--paper", metavar="DIR", help="also a folder in the SIDAR paper's layout")
    table.add_argument("--chosen-on", type=int, default=3, metavar="N",
                       help="how many of the paper's first sequences were used to choose the recipe (reported apart)")
    table.add_argument("--out", default="out/transfer", help="where homography-v1 is rendered (kept)")
    diagnosis = commands.add_parser("diagnose", help="why the paper's pairs are hard (light, truth, SIFT, content)")
    diagnosis.add_argument("--paper", metavar="DIR", required=True, help="a folder in the SIDAR paper's layout")
    diagnosis.add_argument("--chosen-on", type=int, default=3, metavar="N",
                           help="the paper's first N sequences score the refinement rounds (default 3)")
    diagnosis.add_argument("--threads", type=int, default=os.cpu_count() or 1)
    diagnosis.add_argument("--out", default="out/transfer", help="where the held-out sequences are kept")
    return parser


def main(argv: list[str] | None = None) -> None:
    args = build_parser().parse_args(argv)
    {"train": _train, "record": _record, "table": _table, "diagnose": _diagnose}[args.command](args)


if __name__ == "__main__":
    main()
