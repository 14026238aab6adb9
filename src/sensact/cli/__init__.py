"""The ``sensact`` command (typer), one module per command group (a package, learn/, for the learners); the
only place that configures logging or draws progress bars.

Heavy modules (numba kernels, matplotlib) are imported inside the commands so that ``sensact --help``
stays instant.

* ``base``: the app, its command groups and what every command shares (options, errors, exit codes);
* ``convert`` and ``convert_bag``, ``learn/``, ``evaluate``, ``localize``, ``monitor``, ``fleet``,
  ``export``, ``simulate`` and ``reproduce``: one module per command group; ``scores``: what learning and
  evaluating print of a model;
* ``compiling``: a line while numba compiles; ``reference``: the docs' command reference, from ``--help``.
"""

from sensact.cli import (  # noqa: F401  (each registers its commands, in the order `--help` lists them)
    convert,
    convert_bag,
    evaluate,
    export,
    fleet,
    learn,
    localize,
    monitor,
    reproduce,
    simulate,
)
from sensact.cli.base import app, main

__all__ = ["app", "main"]
