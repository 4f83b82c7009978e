"""The docs stay true: the Python snippets of the README and the pages run as written (dataset,
augmentation, pairs, torchrun), the configuration page's table is the generated schema, and every
relative link resolves."""

import os
import re
import socket
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
README = ROOT / "README.md"
DOCS = ROOT / "docs"
SNIPPET_PAGES = (README, DOCS / "usage.md", DOCS / "distributed.md", DOCS / "ray.md")
"""Where the Python snippets are, in the order a reader meets them."""


def python_blocks() -> list[str]:
    return [block for page in SNIPPET_PAGES
            for block in re.findall(r"^```python\n(.*?)^```", page.read_text(), flags=re.M | re.S)]


def run(code: str, env: dict | None = None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=600,
                          env={**os.environ, **(env or {})}, cwd=README.parent)


def test_every_snippet_is_checked_here():
    blocks = python_blocks()
    assert len(blocks) == 5
    assert "torchrun" in blocks[3] and "torchrun" not in "".join(blocks[:3])
    assert "ray_dataset" in blocks[4] and "ray_dataset" not in "".join(blocks[:4])


@pytest.mark.gl
def test_dataset_augmentation_and_pairs_snippets_run():
    blocks = python_blocks()
    # The pairs snippet continues the augmentation snippet; each runs as a user would paste it.
    code = blocks[0] + "\n" + blocks[1] + "\n" + blocks[2] + "\n" + "assert batch['images'].shape == (8, 6, 3, 384, 512)\n" \
        "assert out['images'].shape == (4, 3, 3, 192, 256)\nassert pairs['corner_offsets'].shape == (4, 4, 2)\n"
    result = run(code)
    assert result.returncode == 0, result.stderr[-2000:]


@pytest.mark.gl
def test_torchrun_snippet_runs_as_a_one_rank_job():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    env = {"RANK": "0", "WORLD_SIZE": "1", "LOCAL_RANK": "0", "MASTER_ADDR": "127.0.0.1", "MASTER_PORT": str(port)}
    code = python_blocks()[3] + "\nassert list(ds.indices())[:3] == [0, 1, 2]\ntorch.distributed.destroy_process_group()\n"
    result = run(code, env)
    assert result.returncode == 0, result.stderr[-2000:]


@pytest.mark.gl
def test_ray_snippet_runs_on_a_local_cluster():
    pytest.importorskip("ray")
    code = python_blocks()[4] + "\nassert images.shape == (4, 6, 3, 192, 256)\nray.shutdown()\n"
    result = run(code)
    assert result.returncode == 0, result.stderr[-2000:]


def test_configuration_page_table_is_the_generated_schema():
    from sidar_torch.config.schema import schema_markdown

    text = (DOCS / "configuration.md").read_text()
    start = text.index("<!-- schema:")
    table = text[text.index("\n", start) + 1:text.index("<!-- end schema -->")].rstrip("\n")
    assert table == schema_markdown()


def test_every_config_field_has_a_meaning_in_the_schema():
    from sidar_torch.config.schema import schema_rows

    assert all(row["meaning"] for row in schema_rows()), [row["name"] for row in schema_rows() if not row["meaning"]]


def test_every_relative_link_of_the_docs_resolves():
    pages = [README, *sorted(DOCS.glob("*.md")), ROOT / "benchmarks" / "README.md", ROOT / "configs" / "README.md"]
    broken = []
    for page in pages:
        for target in re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", page.read_text()):
            if "://" not in target and not (page.parent / target).exists():
                broken.append(f"{page.relative_to(ROOT)} -> {target}")
    assert not broken, broken


def test_readme_is_short_and_cites_nothing_outside_the_project():
    text = README.read_text()
    assert len(text.encode()) <= 15_000
    for page in [README, *DOCS.glob("*.md")]:
        assert "../shared" not in page.read_text() and "anchors/" not in page.read_text(), page.name
