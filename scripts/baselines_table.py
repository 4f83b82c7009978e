"""The table of docs/benchmarks.md: every shipped baseline on test sets, one row each.

    .venv/bin/python scripts/baselines_table.py --cache ~/.cache/sidar_torch/homography-v1 \\
        --testset homography-v1 --testset PATH/TO/PAPER/SEQUENCES --json-dir results/

Each cell is ``sidar_torch.evaluate(name, testset=..., cache=...)`` (what ``python -m sidar_torch
evaluate --testset T --estimator NAME`` prints); ``--json-dir`` keeps each result as JSON. A
baseline that cannot run (OpenCV missing, no HomographyNet weights) gets a row saying why.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from sidar_torch import evaluate
from sidar_torch.evaluation.baselines import ESTIMATORS


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--testset", action="append", required=True, help="a shipped set's name or a folder (repeat)")
    parser.add_argument("--cache", default=None, help="where a named set is rendered (kept)")
    parser.add_argument("--json-dir", default=None, help="write each result as <set>-<estimator>.json here")
    parser.add_argument("--estimator", action="append", default=None, help="only these baselines (repeat)")
    args = parser.parse_args()
    names = args.estimator or [name for name in ESTIMATORS]
    print("| set | estimator | pairs | MACE (px) | median (px) | <= 1 px | <= 3 px | <= 10 px | failures | ms per pair |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for testset in args.testset:
        label = testset if Path(testset).name == testset else f"{Path(testset).name}/"
        for name in names:
            try:
                result = evaluate(name, testset=testset, cache=args.cache)
            except (ImportError, FileNotFoundError) as error:
                print(f"| {label} | {name} | not run: {error} |", flush=True)
                continue
            if args.json_dir:
                Path(args.json_dir).mkdir(parents=True, exist_ok=True)
                (Path(args.json_dir) / f"{Path(testset).name}-{name}.json").write_text(json.dumps(result, indent=1))
            success = " | ".join(f"{100 * result['success'][px]:.0f} %" for px in ("1", "3", "10"))
            print(f"| {label} | {name} | {result['pairs']} | {result['mace']:.2f} | {result['median_error']:.2f} | "
                  f"{success} | {result['failures']} | {result['median_seconds'] * 1e3:.0f} |", flush=True)


if __name__ == "__main__":
    main()
