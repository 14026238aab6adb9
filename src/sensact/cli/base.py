"""The ``sensact`` Typer app, its command groups, and what every command shares: the consoles, bad input
as one line and exit code 2, progress bars, result tables, and the layering of defaults, ``--config``
and ``--set``."""

from __future__ import annotations

import functools
import inspect
import logging
import os
import sys
import warnings
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Annotated, Any, TypeVar

import typer
from rich.console import Console
from rich.markup import escape
from rich.table import Table

from sensact.errors import EXIT_BAD_INPUT, EXIT_FLAGGED, EXIT_INTERNAL, EXIT_INTERRUPTED, SensactError
from sensact.records import JsonObject

# help is plain text: a bracket in it ("sensact[fleet]") is not rich markup, which would drop it
PLAIN: JsonObject = {"rich_markup_mode": None}
app = typer.Typer(
    **PLAIN,
    name="sensact",
    help="Learn a mobile robot's action and sensor models from its own logs, with no ground truth "
    "(Stronger 2008). Start with `sensact reproduce` or docs/tutorial.md; every command: docs/cli-reference.md.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)
simulate_app = typer.Typer(**PLAIN, help="Write a simulated log folder (with its ground truth).", no_args_is_help=True)
learn_app = typer.Typer(**PLAIN, help="Learn models from a log.", no_args_is_help=True)
app.add_typer(simulate_app, name="simulate")
app.add_typer(learn_app, name="learn")
convert_app = typer.Typer(**PLAIN, help="Turn a dataset into a sensact log folder.", no_args_is_help=True)
evaluate_app = typer.Typer(
    **PLAIN,
    help="Score learned models against a dataset's ground truth, and a fleet's models on each other's logs.",
    no_args_is_help=True,
)
app.add_typer(convert_app, name="convert")
app.add_typer(evaluate_app, name="evaluate")

# rich falls back to 80 columns when output is not a terminal; the result tables need more
console = Console(width=None if sys.stdout.isatty() else 160)
err_console = Console(stderr=True, width=None if sys.stderr.isatty() else 160)
_state = {"debug": False}
F = TypeVar("F", bound=Callable[..., Any])

SetOpt = Annotated[
    list[str] | None, typer.Option("--set", help="Override a config field: --set name=value (repeatable).")
]
ConfigOpt = Annotated[Path | None, typer.Option("--config", help="YAML file of config fields.")]
WorkersOpt = Annotated[
    int | None,
    typer.Option(
        "--workers",
        help="Run the jobs on a Dask LocalCluster of this many worker processes (the fleet extra: "
        "pip install 'sensact[fleet]'); 1 runs them here, one after another.",
    ),
]
SchedulerOpt = Annotated[
    str | None,
    typer.Option(
        "--scheduler",
        help="Run the jobs on the Dask cluster at this address (tcp://host:8786) instead; its workers need sensact "
        "and the same paths to the logs.",
    ),
]
UncertaintyOpt = Annotated[
    str | None,
    typer.Option(
        "--uncertainty",
        metavar="information|B",
        help="Then give every learned parameter a 90 % interval: 'information' from the likelihood's curvature "
        "(action, f, mount) and profiles (the sigmas and Sigma_m; open-ended where the log gives no bound), with "
        "no refits; or B, a parametric bootstrap of B logs drawn from the learned model, each learned again. "
        "Written into the model JSON (uncertainty) and onto the report (docs/uncertainty.md).",
    ),
]
EMModelOpt = Annotated[Path, typer.Option("--model", help="A model.json written by `sensact learn em`.")]
EMLogArg = Annotated[
    Path,
    typer.Argument(help="A log folder (planar, a 1-D track, or wheels and a 2-D lidar), or a Turtlebot CSV file."),
]


def friendly(fn: F) -> F:
    """Every way a command ends, as one line and a documented exit code (``sensact.errors``): bad input 2,
    Ctrl-C or SIGTERM 130, anything unexpected 70 ("internal error"); ``--debug`` shows the traceback
    instead. Exit 3 (written but flagged) is the command's own ``raise typer.Exit(EXIT_FLAGGED)``."""

    @functools.wraps(fn)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        from sensact.cli.compiling import announce_compiles
        from sensact.io.atomic import one_run

        say = functools.partial(err_console.print, style="dim", highlight=False, soft_wrap=True, markup=False)
        with _sigterm_as_interrupt(), one_run(), announce_compiles(say):
            try:
                if isinstance(kwargs.get("seed"), int):  # every command's --seed, before any work
                    from sensact.config import refuse_non_finite

                    refuse_non_finite(kwargs["seed"], None, "--seed", "the command line")
                return fn(*args, **kwargs)
            except (typer.Exit, typer.Abort):
                raise  # typer.Exit is a RuntimeError: the command's own exit code, as it chose
            except SensactError as exc:
                if _state["debug"]:
                    raise
                # escaped: a message's own brackets ("sensact[ros]", "[fwd, left, yaw]") are not markup
                err_console.print(f"[bold red]error:[/] {escape(str(exc))}", highlight=False, soft_wrap=True)
                raise typer.Exit(EXIT_BAD_INPUT) from None
            except OSError as exc:  # a path the system refused: an --out over a file, no permission, a full disk
                if _state["debug"]:
                    raise
                err_console.print(f"[bold red]error:[/] {escape(os_error_line(exc))}", highlight=False, soft_wrap=True)
                raise typer.Exit(EXIT_BAD_INPUT) from None
            except KeyboardInterrupt:
                err_console.print("interrupted; files already written are complete (atomic writes).")
                raise typer.Exit(EXIT_INTERRUPTED) from None
            except Exception as exc:  # the last line of defence: a bug, never a traceback
                if _state["debug"] or any(_is(exc, n) for n in ("Exit", "ClickException", "Abort")):
                    raise  # click's own (typer's copy or click itself, matched by name): its exit, as it chose
                err_console.print(escape(internal_error_line(exc)), highlight=False, soft_wrap=True)
                raise typer.Exit(EXIT_INTERNAL) from None

    wrapper.__doc__ = one_line_paragraphs(fn.__doc__)
    return wrapper  # type: ignore[return-value]


def finish(health: Any = None, *, interrupted: bool = False) -> None:
    """End a command that wrote its result: exit 130 when it was interrupted (what it wrote is the best so
    far), exit 3 when its ``sensact.health.Health`` flags it, each flag on a line; else return (exit 0)."""
    if interrupted:
        err_console.print("interrupted: what was written is the best so far, and it is complete.")
        raise typer.Exit(EXIT_INTERRUPTED)
    if health is not None and not health.ok:
        for flag in health.flags:
            err_console.print(
                f"[bold yellow]flagged ({flag.code}):[/] {escape(flag.message)}", highlight=False, soft_wrap=True
            )
        raise typer.Exit(EXIT_FLAGGED)


def internal_error_line(exc: BaseException) -> str:
    from sensact import __version__

    what = " ".join(str(exc).split())[:300] or "(no message)"
    return f"internal error: {type(exc).__name__}: {what} (sensact {__version__}); run with --debug and report it."


@contextmanager
def _sigterm_as_interrupt() -> Iterator[None]:
    """SIGTERM (a scheduler's kill, ``timeout``) ends a command as Ctrl-C does: the write under way is
    dropped with its temporary file, what was finished stays, and the exit code is 130."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def interrupt(signum: int, frame: Any) -> None:
        raise KeyboardInterrupt

    previous = signal.signal(signal.SIGTERM, interrupt)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


SIBLING_SUFFIXES = (".png", ".npz", ".html")  # what a command writes beside its JSON --out


ForceOpt = Annotated[
    bool, typer.Option("--force", help="Replace a file at --out that is not a sensact output of this kind.")
]


def check_out_file(
    out: Path | None,
    option: str = "--out",
    *,
    others: dict[str, Path | None] | None = None,
    kind: str | None = None,
    force: bool = False,
) -> None:
    """Refuse, before any work, an output path that is not a regular file or a new path (a folder, a device
    such as /dev/full, which the atomic rename would replace), a JSON output named as one of the files
    written beside it (``model.png`` would be overwritten by the figure), a path another output of the
    same command also writes or reads (``others``: option name to path; never overridden: a command writes
    over none of its inputs), and, unless ``force``, an existing file that
    is not a sensact output of ``kind`` (``write_result``'s stamp): a user's own file is never replaced
    silently."""
    from sensact.errors import ConfigError
    from sensact.outputs import is_output_of

    if out is None:
        return
    if out.exists() and not out.is_file():
        kind = "a folder" if out.is_dir() else "not a regular file (a device, a pipe or a socket)"
        raise ConfigError(
            f"{out} is {kind}, and writing the result would replace it.",
            field=option,
            fix="give the path of a regular file, or a new one.",
        )
    if out.suffix.lower() in SIBLING_SUFFIXES:
        raise ConfigError(
            f"{out} ends in {out.suffix}, the name of a file this command writes beside its JSON, which would "
            "overwrite it.",
            field=option,
            fix=f"give a .json path, e.g. {out.with_suffix('.json')}.",
        )
    for name, path in (others or {}).items():
        if path is not None and path.resolve() == out.resolve():
            raise ConfigError(f"{option} and {name} are both {out}.", field=option, fix="give each its own path.")
    if kind is not None and out.is_file() and not force and not is_output_of(out, kind):
        raise ConfigError(
            f"{out} exists and is not a sensact {kind}; writing here would replace it.",
            field=option,
            fix="give a new path, or pass --force to replace it.",
        )


def os_error_line(exc: OSError) -> str:
    """The file, what the system said, and a fix for the usual causes, as every other error is shown."""
    import errno

    fixes = {
        errno.EEXIST: "a file stands where a folder is needed; choose another --out or move the file.",
        errno.ENOTDIR: "a file stands where a folder is needed; choose another --out or move the file.",
        errno.EISDIR: "give a file here, not a folder.",
        errno.EACCES: "choose a path you may read or write, or change its permissions.",
        errno.EPERM: "choose a path you may read or write, or change its permissions.",
        errno.ENOSPC: "free some space, or write the results to another disk with --out.",
        errno.ENOENT: "check the path.",
    }
    fix = fixes.get(exc.errno or 0, "check the path and the permissions.")
    where = exc.filename if exc.filename is not None else "(no file named)"
    return str(SensactError(f"{exc.strerror or exc}.", file=str(where), fix=fix))


def one_line_paragraphs(doc: str | None) -> str | None:
    """A docstring with each paragraph on one line, for ``--help`` to wrap at the terminal's width: Typer
    keeps a docstring's own line breaks after the first paragraph, which at 80 columns breaks every
    line twice. A paragraph starting with ``\\b`` (click's "keep my lines") is left as written."""
    if not doc:
        return doc
    paragraphs = inspect.cleandoc(doc).split("\n\n")
    return "\n\n".join(p if p.startswith("\b") else " ".join(p.split()) for p in paragraphs)


def _print_version(given: bool) -> None:
    if given:
        from sensact import __version__

        console.print(f"sensact {__version__}")
        raise typer.Exit()


@app.callback()
def _main(
    debug: Annotated[bool, typer.Option("--debug", help="Show full tracebacks.")] = False,
    verbose: Annotated[bool, typer.Option("--verbose", "-v", help="Log library messages.")] = False,
    version: Annotated[
        bool, typer.Option("--version", callback=_print_version, is_eager=True, help="Print the version and exit.")
    ] = False,
) -> None:
    _state["debug"] = debug
    logging.basicConfig(level=logging.DEBUG if verbose else logging.WARNING, format="%(name)s: %(message)s")
    # a LocalCluster's scheduler and nannies run in this process and tell every worker's start and stop, and a
    # worker whose heartbeat meets the closed scheduler at the end logs a traceback; a job's own failure comes
    # back as its result. Dask reads its log level when imported (and its workers inherit it).
    os.environ.setdefault("DASK_LOGGING__DISTRIBUTED", "info" if verbose else "critical")


class ProgressRows:
    """Which row of a progress bar a library ``progress(description, done, total)`` call moves: the row
    with that description; else the row whose label (the description up to its first ": ") is the same,
    relabelled (jobs running at once, each naming itself: "diffdrive seed1: EM iteration 40, ..."); else
    the last row, relabelled, while its count climbs toward the same total (EM's description carries the
    current log-likelihood, so it changes every iteration); else a new row (the next trial starts again
    from 1)."""

    def __init__(self, bar: Any) -> None:
        self.bar = bar
        self.rows: JsonObject = {}
        self.labels: JsonObject = {}
        self.last: tuple[Any, int, int | None] | None = None  # (task, done, total) of the last call
        self.totals: dict[Any, int | None] = {}  # each row's total as last given

    def __call__(self, desc: str, done: int, total: int | None) -> None:
        label = desc.split(": ", 1)[0] if ": " in desc else None
        task = self.rows.get(desc)
        if task is None and label is not None:
            task = self.labels.get(label)
        if task is None and self.last is not None and self.last[2] == total and done > self.last[1]:
            task = self.last[0]
            self.rows = {k: v for k, v in self.rows.items() if v != task}
            self.labels = {k: v for k, v in self.labels.items() if v != task}
        if task is not None and total is None and self.totals.get(task) is not None:
            task = None  # a count with no end after one with an end (a race, then EM): rich keeps an old total
        if task is None:
            task = self.bar.add_task(desc, total=total)
        self.rows[desc] = task
        if label is not None:
            self.labels[label] = task
        if total is not None and done > total:  # never a count over its total (an estimate that fell short)
            total = done
        self.bar.update(task, description=desc, completed=done, total=total)
        self.totals[task] = total
        self.last = (task, done, total)


def _remaining_column() -> Any:
    """Time left as this row's own pace says it: its elapsed time over its count, times what is left.
    (rich's column forgets its pace whenever a total changes, as EM's projected total does.)"""
    from rich.progress import ProgressColumn
    from rich.text import Text

    class Remaining(ProgressColumn):
        def render(self, task: Any) -> Text:
            if task.total is None or not task.completed or task.elapsed is None:
                return Text("-:--:--", style="progress.remaining")
            left = int(task.elapsed / task.completed * max(task.total - task.completed, 0) + 0.5)
            return Text(f"{left // 3600}:{left // 60 % 60:02d}:{left % 60:02d}", style="progress.remaining")

    return Remaining()


@contextmanager
def progress_bar(to: Console | None = None) -> Iterator[Callable[[str, int, int | None], None]]:
    """A rich progress bar fed by the library's ``progress(description, done, total)`` callbacks
    (``total`` None: a count with no end known, as EM's, which stops when it converges)."""
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
    )
    from rich.table import Column

    with Progress(
        # the description gives way first: at 80 columns the count, the time and the ETA stay whole
        TextColumn("{task.description}", table_column=Column(ratio=1, no_wrap=True, overflow="ellipsis")),
        BarColumn(bar_width=12),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        _remaining_column(),  # EM's total is projected from its convergence rate (learn/em/progress.py)
        console=to or err_console,
        transient=False,
        disable=not (to or err_console).is_terminal,
        expand=True,
    ) as bar:
        yield ProgressRows(bar)


def titled_table(title: str) -> Table:
    """A table at least as wide as its title (as the terminal allows), so that a narrow table's title is not
    wrapped word by word."""
    return Table(title=title, title_justify="left", min_width=min(len(title), console.width))


def print_tables(tables: list[tuple[str, list[str], list[list[str]]]]) -> None:
    for title, headers, rows in tables:
        t = titled_table(title)
        for h in headers:
            t.add_column(h)
        for r in rows:
            t.add_row(*r)
        console.print(t)


def write_result(path: Path, doc: JsonObject, kind: str | None = None) -> Path:
    """A model or result JSON, atomically, stamped first with the sensact version that wrote it (what EM
    learns from a log has changed between versions, so a model names the code it came from) and with what
    it is (``kind``: ``check_out_file`` replaces only an output of the same kind)."""
    from sensact import __version__
    from sensact.io.atomic import write_json
    from sensact.outputs import OUTPUT_KEY

    stamp = {"sensact_version": __version__} | ({OUTPUT_KEY: kind} if kind else {})
    return write_json(path, stamp | doc)


def write_results(out: Path, name: str, res: JsonObject, tables: list[Any]) -> None:
    """``out/<name>.json`` and ``out/<name>.md``, and the tables on the console. An experiment's
    ``scorecard`` goes to the Markdown as a table and to the console as one line."""
    from sensact.io.atomic import write_text
    from sensact.report.tables import scorecard_table, to_markdown

    out.mkdir(parents=True, exist_ok=True)
    write_result(out / f"{name}.json", res)
    cards = [scorecard_table(res["scorecard"])] if res.get("scorecard") else []
    write_text(out / f"{name}.md", to_markdown([*tables, *cards]))
    print_tables(tables)
    if res.get("scorecard"):
        from sensact.evaluate.bars import checks_from_json

        print_verdict(name, checks_from_json(res["scorecard"]))


def print_verdict(name: str, checks: list[Any]) -> None:
    """``track1d bars: 12 of 12 cleared``, each miss named (``evaluate.bars.BarCheck``); red when one missed."""
    from rich.text import Text

    from sensact.evaluate.bars import verdict_line

    missed = any(c.cleared is False for c in checks)
    console.print(Text(f"{name} {verdict_line(checks)}", style="bold red" if missed else "bold"))


def config_beside(log: Path, name: str, config: Path | None) -> Path | None:
    """``config``, or else the settings file ``name`` that `convert` or `simulate` wrote beside the log
    folder, said to the user."""
    from sensact.app.settings import settings_beside

    chosen = settings_beside(log, name, config)
    if chosen is not None and chosen != config:
        console.print(f"settings: {chosen}, written beside the log; --config replaces them, --set overrides them.")
    return chosen


def _is(exc: BaseException, name: str) -> bool:
    """Whether ``exc`` is click's exception ``name``: typer 0.29 raises those of its own copy of click, earlier
    typers click's, so the class is matched by name."""
    return any(c.__name__ == name for c in type(exc).__mro__)


def usage_error_line(exc: Any) -> str:
    """A wrong option or argument (click's UsageError) as one line, as every other bad input ends (click's
    own ending prints three)."""
    ctx = getattr(exc, "ctx", None)
    where = ctx.command_path if ctx is not None else "sensact"
    return f"error: {exc.format_message().rstrip('.')}. Fix: see `{where} --help`."


def _warning_line(message, category, filename, lineno, file=None, line=None) -> None:
    """A library's warning as one line of the user's, without the source path it was raised at (--debug: as
    Python shows it)."""
    if _state["debug"]:
        _python_warning(message, category, filename, lineno, file, line)
        return
    err_console.print(f"[yellow]warning:[/] {escape(' '.join(str(message).split()))}", highlight=False, soft_wrap=True)


_python_warning = warnings.showwarning


def main() -> None:
    """Console-script entry point."""
    warnings.showwarning = _warning_line
    try:
        try:
            code = app(standalone_mode=False, prog_name="sensact")  # click's errors come here, to end in one line
        except Exception as exc:
            if _is(exc, "NoArgsIsHelpError"):  # `sensact learn`: its help, as --help prints it
                err_console.print(escape(exc.format_message()), highlight=False, soft_wrap=True)  # type: ignore[attr-defined]
                sys.exit(EXIT_BAD_INPUT)
            if _is(exc, "UsageError"):
                err_console.print(escape(usage_error_line(exc)), highlight=False, soft_wrap=True)
                sys.exit(EXIT_BAD_INPUT)
            if _is(exc, "Abort"):  # click's name for Ctrl-C while it parses
                sys.exit(EXIT_INTERRUPTED)
            if _is(exc, "ClickException"):
                err_console.print(f"error: {escape(exc.format_message())}", highlight=False, soft_wrap=True)  # type: ignore[attr-defined]
                sys.exit(getattr(exc, "exit_code", EXIT_BAD_INPUT))
            raise
        sys.exit(code if isinstance(code, int) else 0)
    except SensactError as exc:  # raised outside a command, e.g. while parsing
        if _state["debug"]:
            raise
        err_console.print(f"error: {escape(str(exc))}", highlight=False, soft_wrap=True)
        sys.exit(EXIT_BAD_INPUT)
    except KeyboardInterrupt:
        sys.exit(EXIT_INTERRUPTED)
    except Exception as exc:
        if _state["debug"]:
            raise
        err_console.print(escape(internal_error_line(exc)), highlight=False, soft_wrap=True)
        sys.exit(EXIT_INTERNAL)
