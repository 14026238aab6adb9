"""The command reference of the docs site (docs/cli-reference.md), generated from the CLI's own help so
that the two cannot drift: ``python -m sensact.cli.reference > docs/cli-reference.md``. A test fails when
the committed page is stale."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

HEADER = """# Command reference

Generated from `sensact --help` and each command's own help by `python -m sensact.cli.reference >
docs/cli-reference.md` (a test fails when this page is stale). The input formats are in
[Log formats](formats.md); what each learner does is on its own page (see the site's index).
"""


def leaf_commands() -> Iterator[tuple[tuple[str, ...], Any]]:
    """Every command that runs something, as (its words after `sensact`, the command), in help order."""
    import typer

    from sensact.cli import app

    def walk(cmd: Any, path: tuple[str, ...]) -> Iterator[tuple[tuple[str, ...], Any]]:
        if hasattr(cmd, "commands"):
            for name, sub in cmd.commands.items():
                yield from walk(sub, (*path, name))
        else:
            yield path, cmd

    yield from walk(typer.main.get_command(app), ())


def _default(p: Any) -> str:
    d = p.default
    if p.required or d is None or not p.show_default or callable(d):
        return ""
    if isinstance(d, bool):
        return ("on" if d else "off") if not p.secondary_opts else (p.opts[0] if d else p.secondary_opts[0])
    if isinstance(d, list | tuple):
        return "" if not d else ", ".join(map(str, d))
    return f"{d:.6g}" if isinstance(d, float) else str(d)


def _cell(text: str | None) -> str:
    return (text or "").replace("|", "\\|").replace("\n", " ")


def command_markdown(path: tuple[str, ...], cmd: Any) -> str:
    args = [p for p in cmd.params if p.param_type_name == "argument"]
    opts = [p for p in cmd.params if p.param_type_name == "option" and not p.hidden]
    usage = " ".join(["sensact", *path, *(p.name.upper() for p in args), "[OPTIONS]" if opts else ""]).strip()
    blocks = [f"## `sensact {' '.join(path)}`", f"```\n{usage}\n```"]
    blocks += [para.strip() for para in (cmd.help or "").split("\n\n") if para.strip() not in ("", "\b")]
    rows = [f"| `{p.name.upper()}` | {_cell(p.help)} | |" for p in args]
    for p in opts:
        names = " / ".join(f"`{o}`" for o in (*p.opts, *p.secondary_opts))
        rows.append(f"| {names} | {_cell(p.help)} | {_cell(_default(p))} |")
    if rows:
        blocks.append("\n".join(["| argument or option | what it is | default |", "|---|---|---|", *rows]))
    return "\n\n".join(blocks) + "\n"


def exit_codes() -> str:
    """Every command's exit codes, from ``sensact.errors`` (what a script tests)."""
    from sensact import errors

    rows = [
        (errors.EXIT_OK, "success: the result is written and healthy"),
        (errors.EXIT_BAD_INPUT, "bad input: one line naming the file, the field and the fix; nothing is written"),
        (
            errors.EXIT_FLAGGED,
            "written but flagged: the fit did not converge or is degenerate; the JSON's `health` lists why "
            "([Bad input and flags](errors.md))",
        ),
        (errors.EXIT_INTERNAL, "internal error: a bug, as one line; run again with `--debug` and report it"),
        (
            errors.EXIT_INTERRUPTED,
            "interrupted (Ctrl-C or SIGTERM): what was finished is on disk, whole; `learn em` writes its most likely "
            "model so far",
        ),
    ]
    table = "\n".join(["| exit code | meaning |", "|---|---|", *(f"| {c} | {m} |" for c, m in rows)])
    return f"\n## Exit codes\n\n{table}\n"


def render() -> str:
    return HEADER + exit_codes() + "".join("\n" + command_markdown(path, cmd) for path, cmd in leaf_commands())


if __name__ == "__main__":
    print(render(), end="")
