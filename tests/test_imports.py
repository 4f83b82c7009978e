"""No two files of the repository import each other (the package, benchmarks, tests, scripts, examples),
whether at the top of a module or inside a function: read with ``ast``, nothing is imported."""

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
FOLDERS = ("sidar_torch", "benchmarks", "tests", "scripts", "examples")


def module_files(root: Path) -> dict[str, Path]:
    """Dotted module name -> file, for every ``.py`` file under the :data:`FOLDERS` of ``root``."""
    files = {}
    for path in (p for folder in FOLDERS for p in sorted((root / folder).rglob("*.py"))):
        parts = path.relative_to(root).with_suffix("").parts
        files[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return files


def imported(name: str, path: Path, modules: dict[str, Path]) -> set[str]:
    """The modules of ``modules`` that the file ``path`` (module ``name``) imports: ``from P import X``
    counts as importing ``P.X`` where that is a module, else ``P`` (a submodule's import of its
    package, which Python does for every submodule, is not counted)."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parent = package.split(".")[:len(package.split(".")) - node.level + 1]
                base = ".".join([*parent, base] if base else parent)
            found.update(f"{base}.{a.name}" if f"{base}.{a.name}" in modules else base for a in node.names)
    return {module for module in found if module in modules and module != name}


def mutual_imports(root: Path) -> list[tuple[str, str]]:
    """Every pair of modules under ``root`` that import each other, sorted."""
    modules = module_files(root)
    graph = {name: imported(name, path, modules) for name, path in modules.items()}
    return sorted((a, b) for a in graph for b in graph[a] if a < b and a in graph[b])


def test_no_two_files_of_the_repository_import_each_other():
    assert mutual_imports(ROOT) == []


def test_a_pair_importing_each_other_is_found_even_inside_a_function(tmp_path):
    (tmp_path / "benchmarks").mkdir()
    (tmp_path / "benchmarks" / "__init__.py").write_text("")
    (tmp_path / "benchmarks" / "a.py").write_text("from benchmarks.b import f\n")
    (tmp_path / "benchmarks" / "b.py").write_text("def f():\n    from . import a\n")
    (tmp_path / "benchmarks" / "c.py").write_text("from . import a\n")  # one way only: not a pair
    assert mutual_imports(tmp_path) == [("benchmarks.a", "benchmarks.b")]


def test_a_submodule_importing_a_sibling_does_not_count_as_importing_its_package(tmp_path):
    (tmp_path / "sidar_torch").mkdir()
    (tmp_path / "sidar_torch" / "__init__.py").write_text("from .sources import S\n")
    (tmp_path / "sidar_torch" / "sources.py").write_text("from . import procedural\nS = 1\n")
    (tmp_path / "sidar_torch" / "procedural.py").write_text("")
    assert mutual_imports(tmp_path) == []
