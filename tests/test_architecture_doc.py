"""docs/architecture.md names code that exists: every `module.name` or `Class.name` it writes in
backticks is defined in that module's file (or the file defining that class) under ``sidar_torch/``
(file names such as `sample.py` are checked by ``tests/test_docs.py``)."""

import re
from pathlib import Path

FILE_SUFFIXES = {"py", "md", "json", "yaml", "frag", "vert", "glsl", "npy", "png", "mat"}
"""What ends a file name, not a code name."""

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "sidar_torch"


def defining_files(owner: str) -> list[Path]:
    """The package files that ``owner`` names: the module ``owner.py`` (or package ``owner/``), else the
    files that define a class ``owner``; empty for a name outside the package (``numpy``, ``kornia``)."""
    modules = [*PACKAGE.rglob(f"{owner}.py"), *PACKAGE.rglob(f"{owner}/__init__.py")]
    return modules or [p for p in PACKAGE.rglob("*.py") if re.search(rf"^class {owner}\b", p.read_text(), re.M)]


def missing_names(text: str) -> list[str]:
    """The backticked ``owner.name`` references of ``text`` whose owner is in the package and whose
    name no file of that owner defines (as a function, class, method or assigned name)."""
    missing = []
    for owner, name in sorted(set(re.findall(r"`(\w+)\.(\w+)[`(]", text))):
        if name in FILE_SUFFIXES:
            continue
        files = defining_files(owner)
        pattern = rf"^\s*(?:def|class) {name}\b|^\s*{name}\s*[:=]"
        if files and not any(re.search(pattern, f.read_text(), re.M) for f in files):
            missing.append(f"{owner}.{name}")
    return missing


def test_every_name_the_architecture_page_gives_exists():
    text = (ROOT / "docs" / "architecture.md").read_text()
    assert len(re.findall(r"`(\w+)\.(\w+)[`(]", text)) > 10  # the page names code
    assert missing_names(text) == []


def test_a_name_that_is_gone_is_found():
    assert missing_names("`warm_up.warm_up_renderer`, `SceneRenderer.render(sequence)`, `numpy.zeros`") == []
    assert missing_names("`warm_up.sample_renderer` and `SceneRenderer.draw_all(view)`") == [
        "SceneRenderer.draw_all", "warm_up.sample_renderer"]  # a name that went (issue 47 item 4)
