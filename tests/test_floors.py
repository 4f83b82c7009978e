"""The floors of docs/architecture.md are the package's folders: every module of ``sidar_torch`` is on
exactly one floor of the page's table, and no module imports one on a higher floor (read with ``ast``
by ``test_imports.imported``, at the top of a module or inside a function)."""

import re
from pathlib import Path

from test_imports import imported, module_files

ROOT = Path(__file__).resolve().parents[1]
MAX_LOOSE_MODULES = 8
"""Modules directly in ``sidar_torch/`` beside its packages (``__init__`` and ``__main__`` included)."""


def floors(page: str) -> list[list[str]]:
    """The floors of the architecture page's table, bottom first, each as the dotted module prefixes of
    its ``folders`` column (`config/` -> ``sidar_torch.config``, `cli.py` -> ``sidar_torch.cli``, a
    folder's files named in parentheses after it are its own and not read)."""
    table = page[page.index("## The floors"):page.index("### Inside `render/`")]
    rows = [line.split("|")[2] for line in table.splitlines() if line.startswith("| ") and "---" not in line][1:]
    result = []
    for cell in reversed(rows):
        top_level = re.sub(r"\([^)]*\)", "", cell)
        prefixes = []
        for name in re.findall(r"`([\w/.]+)`", top_level):
            stem = name.removesuffix("/").removesuffix(".py")
            prefixes.append("sidar_torch" if stem == "__init__" else f"sidar_torch.{stem}")
        result.append(prefixes)
    return result


def floor_of(module: str, table: list[list[str]]) -> list[int]:
    """The floors whose prefixes hold ``module`` (its own module or a folder above it)."""
    return [i for i, prefixes in enumerate(table)
            if any(module == p or (module.startswith(p + ".") and p != "sidar_torch") for p in prefixes)]


def upward_imports(root: Path, page: str) -> tuple[list[str], list[str]]:
    """The package modules on no floor or on several, and every import of a module on a higher floor."""
    table = floors(page)
    modules = {name: path for name, path in module_files(root).items() if name.split(".")[0] == "sidar_torch"}
    misplaced = [name for name in sorted(modules) if len(floor_of(name, table)) != 1]
    upward = []
    for name, path in sorted(modules.items()):
        if name in misplaced:
            continue
        for dependency in sorted(imported(name, path, modules)):
            if dependency not in misplaced and floor_of(dependency, table)[0] > floor_of(name, table)[0]:
                upward.append(f"{name} imports {dependency}")
    return misplaced, upward


def test_every_module_is_on_one_floor_and_imports_only_floors_under_it():
    page = (ROOT / "docs" / "architecture.md").read_text()
    assert len(floors(page)) >= 8
    assert upward_imports(ROOT, page) == ([], [])


def test_the_package_has_few_loose_modules():
    loose = sorted(path.name for path in (ROOT / "sidar_torch").glob("*.py"))
    assert len(loose) <= MAX_LOOSE_MODULES, loose


def test_an_import_from_a_higher_floor_and_a_module_on_no_floor_are_found(tmp_path):
    package = tmp_path / "sidar_torch"
    (package / "low").mkdir(parents=True)
    (package / "__init__.py").write_text("")
    (package / "low" / "__init__.py").write_text("")
    (package / "low" / "a.py").write_text("def f():\n    from ..high import b\n")
    (package / "high.py").write_text("from .low import a\n")
    (package / "stray.py").write_text("")
    page = ("## The floors\n\n| floor | folders | what |\n|---|---|---|\n"
            "| top | `__init__.py`, `high.py` | x |\n| bottom | `low/` (`a.py`) | y |\n\n### Inside `render/`\n")
    assert upward_imports(tmp_path, page) == (["sidar_torch.stray"], ["sidar_torch.low.a imports sidar_torch.high"])
