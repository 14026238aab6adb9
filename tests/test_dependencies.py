"""Every import in the package is a declared dependency: module-level imports are base dependencies (a bare
``pip install .`` runs every command), and an optional extra's package is imported only inside the function that
needs it. ``.ci/run`` checks the same in a bare virtual environment by importing every module
(``tests/bare_install.py``); this test says which import broke it, on any machine."""

from __future__ import annotations

import ast
import functools
import re
import sys
import tomllib
from importlib import metadata
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SRC = ROOT / "src" / "sensact"


def _dist(requirement: str) -> str:
    return re.split(r"[\s<>=!~\[;]", requirement, maxsplit=1)[0].lower().replace("_", "-")


def _declared() -> tuple[set[str], set[str]]:
    """The base dependencies, and what the extras add (their own requirements' too, one level down)."""
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    base = {_dist(r) for r in project["dependencies"]}
    extra = {_dist(r) for reqs in project["optional-dependencies"].values() for r in reqs} - {"sensact"}
    for name in list(extra):
        try:
            extra |= {_dist(r) for r in metadata.requires(name) or () if "extra ==" not in r}
        except metadata.PackageNotFoundError:
            pass
    return base, extra


def _import_sites(path: Path) -> list[tuple[str, int, bool]]:
    """Each absolute import's top-level name, its line, and whether it runs when the module is imported (at
    module level, outside ``if TYPE_CHECKING`` and outside a ``try`` that catches ImportError)."""
    tree = ast.parse(path.read_text())
    out: list[tuple[str, int, bool]] = []

    def visit(node: ast.AST, at_import: bool) -> None:
        for child in ast.iter_child_nodes(node):
            eager = at_import
            if isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef | ast.Lambda):
                eager = False
            elif isinstance(child, ast.If) and "TYPE_CHECKING" in ast.unparse(child.test):
                eager = False
            elif isinstance(child, ast.Try) and any(
                "ImportError" in ast.unparse(h.type or ast.Name("")) for h in child.handlers
            ):
                eager = False
            if isinstance(child, ast.Import):
                out.extend((a.name.split(".")[0], child.lineno, eager) for a in child.names)
            elif isinstance(child, ast.ImportFrom) and child.level == 0 and child.module:
                out.append((child.module.split(".")[0], child.lineno, eager))
            visit(child, eager)

    visit(tree, True)
    return out


@functools.cache
def _installed() -> dict[str, list[str]]:
    return metadata.packages_distributions()


def _distributions(module: str) -> set[str]:
    return {d.lower().replace("_", "-") for d in _installed().get(module, [module])}


def test_every_import_is_declared_and_extras_are_imported_lazily():
    base, extra = _declared()
    undeclared, eager_extras = [], []
    for path in sorted(SRC.rglob("*.py")):
        for module, line, eager in _import_sites(path):
            if module in sys.stdlib_module_names or module == "sensact":
                continue
            dists = _distributions(module)
            where = f"{path.relative_to(ROOT)}:{line} imports {module}"
            if not dists & (base | extra):
                undeclared.append(where)
            elif eager and not dists & base:
                eager_extras.append(where)
    assert not undeclared, f"not a declared dependency: {undeclared}"
    assert not eager_extras, f"an extra's package imported at module level: {eager_extras}"


def test_the_checker_sees_an_undeclared_import(tmp_path):
    """The walk above finds module-level, function-local and guarded imports apart (so the test can fail)."""
    path = tmp_path / "m.py"
    path.write_text(
        "import click\nfrom typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    import dask\n"
        "try:\n    import rosbags\nexcept ImportError:\n    rosbags = None\n"
        "def f():\n    import kiss_icp\n"
    )
    sites = {m: eager for m, _, eager in _import_sites(path)}
    assert sites == {"click": True, "typing": True, "dask": False, "rosbags": False, "kiss_icp": False}
    base, extra = _declared()
    assert "click" not in base  # typer no longer brings it (dask does, in the fleet extra)
    assert {"rosbags", "distributed", "kiss-icp"} <= extra and "numpy" in base
