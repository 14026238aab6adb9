"""The first run's compile: every kernel is cached (compiled once per install) and announced in one line."""

from __future__ import annotations

import ast
import os
import subprocess
import sys
import textwrap
from pathlib import Path

from numba import njit

from sensact.cli.compiling import MESSAGE, announce_compiles

SRC = Path(__file__).resolve().parents[1] / "src" / "sensact"


def _numba_decorators(tree: ast.AST) -> list[ast.expr]:
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.FunctionDef):
            for dec in node.decorator_list:
                target = dec.func if isinstance(dec, ast.Call) else dec
                name = target.attr if isinstance(target, ast.Attribute) else getattr(target, "id", "")
                if name in ("njit", "jit"):
                    found.append(dec)
    return found


def test_every_kernel_is_cached_on_disk():
    """A kernel without cache=True would compile again in every process, not once per install."""
    uncached, total = [], 0
    for path in sorted(SRC.rglob("*.py")):
        for dec in _numba_decorators(ast.parse(path.read_text())):
            total += 1
            keywords = {k.arg: k.value for k in dec.keywords} if isinstance(dec, ast.Call) else {}
            cache = keywords.get("cache")
            if not (isinstance(cache, ast.Constant) and cache.value is True):
                uncached.append(f"{path.relative_to(SRC)}:{dec.lineno}")
    assert total > 30  # the scan sees the kernels (the E-step's, Algorithm 1's, ray casting, packets)
    assert uncached == []


def test_one_line_for_a_compile_however_nested():
    @njit
    def inner(x):
        return x + 1.0

    @njit
    def outer(x):
        return inner(x) * 2.0

    @njit
    def other(x):
        return x - 1.0

    lines: list[str] = []
    with announce_compiles(lines.append) as notice:
        assert outer(1.0) == 4.0
        assert lines == [MESSAGE]
        assert notice.kernels == 1  # inner compiled inside outer's compile
        outer(2.0)  # compiled already: nothing happens
        assert notice.kernels == 1
        other(1.0)
        assert notice.kernels == 2
    assert lines == [MESSAGE]  # said once, however many kernels compile
    other(3.0)
    lines.clear()

    @njit
    def after(x):
        return x

    after(1.0)  # outside the block: the listener is gone
    assert lines == []


def test_a_cached_kernel_is_not_compiled_or_announced_again(tmp_path):
    (tmp_path / "kernel_mod.py").write_text(
        textwrap.dedent(
            """
            from numba import njit

            @njit(cache=True)
            def twice(x):
                return 2.0 * x
            """
        )
    )
    script = textwrap.dedent(
        """
        import sys
        from sensact.cli.compiling import announce_compiles
        with announce_compiles() as notice:
            import kernel_mod
            assert kernel_mod.twice(2.0) == 4.0
        print(notice.kernels)
        """
    )
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache"), "PYTHONPATH": str(tmp_path)}
    runs = [subprocess.run([sys.executable, "-c", script], env=env, capture_output=True, text=True) for _ in range(2)]
    assert [r.returncode for r in runs] == [0, 0], [r.stderr for r in runs]
    assert [r.stdout.strip() for r in runs] == ["1", "0"]
    assert MESSAGE in runs[0].stderr
    assert MESSAGE not in runs[1].stderr
