"""DESIGN.md layering: imports only go downward, and the numerical layers never pull in a UI library."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

SRC = Path(__file__).resolve().parents[1] / "src" / "sensact"
# rank of each top-level part; a module may import only parts of lower rank (or its own part)
RANK = {
    "errors": 0,
    "health": 1,
    "limits": 0,
    "reprs": 0,
    "outputs": 0,
    "records": 0,
    "progress": 0,
    "config": 1,
    "engine": 1,
    "core": 1,
    "models": 2,
    "logs": 2,
    "learn": 3,
    "sim": 3,
    "io": 3,
    "evaluate": 4,
    "presets": 4,
    "report": 5,
    "app": 6,
    "experiments": 7,
    "cli": 8,
    "__main__": 9,
}
UI_LIBS = {"matplotlib", "typer", "rich", "tqdm"}
NUMERIC_PARTS = ("core", "models", "logs", "learn", "sim")


def _imports(path: Path) -> list[str]:
    tree = ast.parse(path.read_text())
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            out.append(node.module)
    return out


def _part(path: Path) -> str:
    rel = path.relative_to(SRC)
    return rel.parts[0].removesuffix(".py")


def test_every_part_has_a_rank():
    parts = {_part(p) for p in SRC.rglob("*.py") if p.name != "__init__.py" or p.parent != SRC}
    assert parts <= set(RANK), parts - set(RANK)


def test_imports_only_go_downward():
    bad = []
    for path in SRC.rglob("*.py"):
        if path.parent == SRC and path.name == "__init__.py":
            continue
        me = _part(path)
        for mod in _imports(path):
            if mod.startswith("sensact."):
                other = mod.split(".")[1]
                if other != me and RANK[other] >= RANK[me]:
                    bad.append(f"{path.relative_to(SRC)} imports {mod}")
    assert not bad, "\n".join(bad)


def test_cli_imports_experiments_only_in_reproduce():
    """The commands' work lives in app/ (DESIGN.md): the CLI parses, calls one app function, prints and
    saves; only `sensact reproduce` runs the thesis's experiments."""
    bad = [
        f"{path.relative_to(SRC)} imports {mod}"
        for path in (SRC / "cli").rglob("*.py")
        if path.name != "reproduce.py"
        for mod in _imports(path)
        if mod.startswith("sensact.experiments")
    ]
    assert not bad, "\n".join(bad)


def test_numeric_layers_name_no_ui_library():
    bad = []
    for part in NUMERIC_PARTS:
        for path in (SRC / part).rglob("*.py"):
            for mod in _imports(path):
                if mod.split(".")[0] in UI_LIBS:
                    bad.append(f"{path.relative_to(SRC)} imports {mod}")
    assert not bad, "\n".join(bad)


def test_numeric_layers_load_no_ui_library_at_runtime():
    code = (
        "import sys, sensact.core.recursive, sensact.core.degree, sensact.models.polynomial, "
        "sensact.learn.bootstrap, sensact.sim.track1d, sensact.learn.em, sensact.sim.field2d, "
        "sensact.core.ekf_smoother, sensact.models.em_model, sensact.core.raycast, sensact.sim.velodyne_car, "
        "sensact.learn.velodyne_car_dynamics, sensact.learn.spinning_lidar_intrinsics; "
        f"print(sorted(m for m in {sorted(UI_LIBS)!r} if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.strip()
    assert out == "[]"


def _module_name(path: Path, src: Path) -> str:
    parts = list(path.relative_to(src.parent).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def import_cycles(src: Path = SRC) -> list[list[str]]:
    """Every set of sensact modules that import each other round a cycle (Tarjan's strongly connected
    components of the import graph, imports inside functions included: they cycle at run time too)."""
    modules = {_module_name(p, src): p for p in src.rglob("*.py")}
    graph: dict[str, set[str]] = {}
    for name, path in modules.items():
        out = set()
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                out |= {a.name for a in node.names}
            elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                # ``from sensact.a import b`` names the module sensact.a.b when there is one
                out |= {
                    f"{node.module}.{a.name}" if f"{node.module}.{a.name}" in modules else node.module
                    for a in node.names
                }
        graph[name] = {m for m in out if m in modules and m != name}
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    cycles: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                cycles.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return cycles


def test_no_import_cycles(tmp_path):
    """No module imports another that imports it back, directly or round a longer cycle; and the check
    finds one (an independent case: two modules written to import each other)."""
    assert import_cycles() == []
    pkg = tmp_path / "sensact"
    (pkg / "a").mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "a" / "__init__.py").write_text("")
    (pkg / "a" / "x.py").write_text("def f():\n    from sensact.a.y import g\n")
    (pkg / "a" / "y.py").write_text("from sensact.a import x\n")
    assert import_cycles(pkg) == [["sensact.a.x", "sensact.a.y"]]


def test_every_package_map_names_its_modules():
    """Each package's docstring is its map: it names every module and subpackage in it (``name``)."""
    bad = []
    for init in SRC.rglob("__init__.py"):
        pkg = init.parent
        doc = ast.get_docstring(ast.parse(init.read_text())) or ""
        names = [p.stem for p in pkg.glob("*.py") if p.name != "__init__.py"]
        names += [d.name for d in pkg.iterdir() if (d / "__init__.py").is_file()]
        bad += [f"{pkg.relative_to(SRC)}: {n}" for n in names if f"``{n}" not in doc]
    assert not bad, "package maps that leave out a module:\n" + "\n".join(sorted(bad))


def _room(path: Path, home: Path) -> str:
    rel = path.relative_to(home)
    return rel.parts[0] if len(rel.parts) > 1 else rel.stem


def test_learn_em_rooms_import_only_downward():
    """learn/em's rooms (each module of its core, each role folder) import one another without a circle, so that
    each sits above all it imports."""
    home = SRC / "learn" / "em"
    edges: dict[str, set[str]] = {}
    for path in home.rglob("*.py"):
        if path.name == "__init__.py":
            continue
        me = _room(path, home)
        for mod in _imports(path):
            if mod.startswith("sensact.learn.em."):
                other = mod.split(".")[3]
                if other != me:
                    edges.setdefault(me, set()).add(other)
    done: set[str] = set()

    def visit(room: str, trail: tuple[str, ...]) -> None:
        assert room not in trail, " -> ".join((*trail, room))
        if room in done:
            return
        for other in edges.get(room, ()):
            visit(other, (*trail, room))
        done.add(room)

    for room in list(edges):
        visit(room, ())
