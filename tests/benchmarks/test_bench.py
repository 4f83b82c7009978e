"""The speed benchmark (``benchmarks/bench.py``) on tiny settings: structure and consistency of the
figures and the target verdicts, never speed (speed is what ``python -m benchmarks.bench`` prints)."""

import json
import math

import pytest

from benchmarks import bench
from benchmarks.common import parse_size, size_label

pytestmark = [pytest.mark.gl, pytest.mark.slow]  # renders a tiny bench run (a module fixture)


@pytest.fixture(scope="module")
def report():
    return bench.run_bench(bench.BenchSettings.quick(), log=lambda line: None)


def test_report_structure_and_consistency(report):
    json.dumps(report)  # plain data
    (row,) = report["views"]
    assert (row["preset"], row["size"], row["views"], row["samples"]) == ("misaligned", "48x64", 2, 2)
    assert 0 < row["s_per_sequence"] < math.inf and row["warmup_s"] > 0 and row["kornia_ms_per_image"] > 0
    assert row["ms_per_view"] == pytest.approx(1e3 * row["s_per_sequence"] / 2)
    assert row["kornia_ratio"] == pytest.approx(row["ms_per_view"] / row["kornia_ms_per_image"])
    a = report["augment"]
    assert (a["batch"], a["views"], a["size"]) == (2, 2, "48x64")
    assert a["ms_per_image"] > 0 and a["kornia_ratio"] == pytest.approx(a["ms_per_image"] / a["kornia_ms_per_image"])
    assert a["plain_ratio"] == pytest.approx(a["ms_per_image"] / a["plain_ms_per_image"])
    w = report["loaders"]
    assert w["scaling"] == pytest.approx(w["sequences_per_s"]["2"] / w["sequences_per_s"]["1"]) and w["scaling"] > 0
    assert w["samples"] == 4  # samples 0..3 with 1 worker and with 2 (loader_rate checks the indices it got)
    assert 0 < w["first_sample_s"] < report["seconds"]
    first = w["first_sample"]  # where the first sample went adds up to it
    assert first["total"] == w["first_sample_s"] and min(first.values()) >= 0
    assert first["start"] + first["warm_up"] + first["sample"] + first["handover"] == pytest.approx(first["total"])
    m = report["machine"]["before"]
    assert m["cpus"] >= 1 and m["load"] >= 0 and report["seconds"] > 0


def test_quick_run_measures_no_target_size_and_says_so(report):
    verdicts = {t["target"].split(":")[0]: t for t in report["targets"]}
    assert len(report["targets"]) == 8
    for t in report["targets"][:5]:  # 48x64 is none of the targets' sizes
        assert t["met"] is None and t["measured"] == "not measured in this run", t
    assert all(t["met"] in (True, False) for t in report["targets"][5:])
    assert "2 DataLoader workers >= 1.8x one worker (on an idle machine)" in verdicts


def test_loader_rows_measure_the_same_samples_whatever_the_workers():
    with pytest.raises(ValueError, match="loader_samples: expected an even number"):
        bench.BenchSettings(loader_samples=5)
    with pytest.raises(ValueError, match=r"samples: expected a positive multiple of workers \(2\), got 3"):
        bench.loader_rate(None, 2, 3, 0)  # raises before it builds a loader


def fake_report(ms_per_view, kornia_ms, s_per_sequence, augment_ratio, pool, scaling, first=0.5):
    views = [{"preset": "misaligned", "size": size_label(size), "views": 6, "s_per_sequence": s_per_sequence,
              "ms_per_view": ms_per_view, "kornia_ms_per_image": kornia_ms, "kornia_ratio": ms_per_view / kornia_ms}
             for size in bench.TARGET_SIZES.values()]
    return {"views": views, "machine": {"before": {"load": 0.1, "cpus": 2}, "after": {"load": 0.2, "cpus": 2}},
            "augment": {"preset": "misaligned", "batch": 8, "views": 2, "size": "192x256", "ms_per_image": 1.0,
                        "kornia_ms_per_image": 1 / augment_ratio, "kornia_ratio": augment_ratio,
                        "plain_ms_per_image": 0.5 / augment_ratio, "plain_ratio": 2 * augment_ratio, "pool_speedup": pool},
            "loaders": {"preset": "misaligned", "size": "384x512", "scaling": scaling, "first_sample_s": first}}


def test_targets_are_judged_on_the_figures_of_the_target_sizes():
    met = bench.targets(fake_report(8.0, 10.0, 0.2, 2.5, 1.8, 1.8))  # at or within every limit
    assert [t["met"] for t in met] == [True] * 8
    missed = bench.targets(fake_report(12.0, 10.0, 0.25, 2.6, None, 1.79, first=0.51))
    # 1.2x kornia: within 24x32's 1.6x and 192x256's 1.3x, over 384x512's 1.1x; no pool: not met, saying why
    assert [t["met"] for t in missed] == [False, True, True, False, False, False, False, False]
    assert missed[0]["measured"] == "0.250 s" and missed[5]["measured"].startswith("no pool")
    assert "1.20x" in missed[3]["measured"] and "1.79x" in missed[6]["measured"] and missed[7]["measured"] == "0.51 s"


def test_parts_not_measured_are_said_so():
    report = {**fake_report(10.0, 10.0, 0.1, 1.0, 2.0, 2.0), "views": [], "loaders": None}
    verdicts = bench.targets(report)
    assert [t["met"] for t in verdicts] == [None] * 4 + [True, True, None, None]
    assert all(t["measured"] == "not measured in this run" for t in verdicts[:4] + verdicts[6:])
    report = {**report, "augment": None, "settings": {}, "heap": "warm", "seconds": 1.0}
    report["machine"]["before"].update(python="3", torch="2", kornia="0", gl_platform="osmesa", lp_num_threads="0")
    text = bench.format_report({**report, "targets": bench.targets(report)})
    assert "## Targets" in text and "SidarAugment against" not in text and "## Per view" not in text
    with pytest.raises(ValueError, match="parts"):
        bench.BenchSettings(parts=("views", "nope"))


def test_five_views_do_not_count_for_the_sequence_target():
    report = fake_report(10.0, 10.0, 0.1, 1.0, 2.0, 2.0)
    for row in report["views"]:
        row["views"] = 5
    assert bench.targets(report)[0]["met"] is None


def test_format_report_prints_every_table_and_verdict(report):
    text = bench.format_report(report)
    assert "| misaligned | 48x64 | 2 |" in text and "size (H x W)" in text
    assert text.count("| - |") >= 5 and "## Targets" in text and "load average" in text
    assert "First sample of the fresh worker (wall clock, s): worker start " in text


def test_settings_reject_bad_values():
    with pytest.raises(ValueError, match="samples"):
        bench.BenchSettings(samples=0)
    with pytest.raises(ValueError, match="sizes"):
        bench.BenchSettings(sizes=((0, 64),))
    with pytest.raises(ValueError, match="augment_batch"):
        bench.BenchSettings(augment_batch=0)
    with pytest.raises(ValueError, match="nope"):
        bench.BenchSettings(presets=("nope",))


def test_sizes_are_height_by_width():
    assert parse_size("384x512") == (384, 512) and size_label((384, 512)) == "384x512"
    for bad in ("512", "0x4", "axb", "384 512"):
        with pytest.raises(Exception, match="HEIGHTxWIDTH"):
            parse_size(bad)


@pytest.mark.parametrize("argv, message", [
    (["--sizes", "64by48"], "HEIGHTxWIDTH"),
    (["--presets", "nope"], "nope"),
    (["--samples", "0"], "samples"),
    (["--parts", "augment", "nope"], "invalid choice: 'nope'"),
])
def test_command_rejects_bad_arguments(argv, message, capsys):
    with pytest.raises(SystemExit) as error:
        bench.main(argv)
    assert message in str(error.value) + capsys.readouterr().err


def test_the_baseline_is_timed_between_the_measured_calls(monkeypatch):
    # Each measured call is followed by its baseline calls, and each side gets its own median.
    calls, clock = [], iter([0.5, 0.1, 0.2, 0.7, 0.3, 0.4, 0.6, 0.5, 0.6])
    monkeypatch.setattr(bench, "cpu_seconds", lambda call: (call(), next(clock))[1])
    ours, theirs = bench.alternated(lambda k: calls.append(f"ours {k}"), lambda: calls.append("kornia"), 3, 2)
    assert calls == ["ours 0", "kornia", "kornia", "ours 1", "kornia", "kornia", "ours 2", "kornia", "kornia"]
    assert (ours, theirs) == (0.6, 0.35)  # medians of 0.5, 0.7, 0.6 and of 0.1, 0.2, 0.3, 0.4, 0.5, 0.6


def test_a_warm_heap_is_asked_for_or_refused_by_name(monkeypatch):
    assert bench.BenchSettings.quick().heap == "cold"  # tests leave the heap alone
    with pytest.raises(ValueError, match="heap"):
        bench.BenchSettings(heap="hot")
    warmed = []
    monkeypatch.setattr(bench, "warm_heap", lambda: warmed.append(True) or True)
    monkeypatch.setattr(bench, "view_row", lambda *args: pytest.fail("stops after the heap"))
    with pytest.raises(pytest.fail.Exception):
        bench.run_bench(bench.BenchSettings.quick(heap="warm"), log=lambda line: None)
    assert warmed == [True]


def test_a_warm_heap_hands_out_touched_pages():
    # Blocks of 2, 4, ..., 30 MiB, each freed before the next: under glibc's defaults a block that
    # outgrows the mmap threshold the last free set is a fresh mapping (about 7800 page faults in
    # all here, or about 650 when the kernel backs the mappings with 2 MiB pages); from a warm heap,
    # pages already touched (0 here).
    import subprocess
    import sys
    from pathlib import Path

    def faults(warm):
        code = ("import resource, numpy as np\nfrom benchmarks.common import warm_heap\n"
                f"assert warm_heap() if {warm} else True\n"
                "before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt\n"
                "for mib in range(2, 32, 2):\n    block = np.ones(mib << 17)\n    del block\n"
                "print(resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before)")
        root = Path(bench.__file__).resolve().parents[1]
        return int(subprocess.run([sys.executable, "-c", code], cwd=root, capture_output=True, text=True,
                                  check=True).stdout)

    cold, warm = faults(False), faults(True)
    assert cold > 300 and warm < cold / 10, (cold, warm)
