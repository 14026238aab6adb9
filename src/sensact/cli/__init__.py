"""The ``sensact`` command (typer), one module per command group (a package, learn/, for the learners); the
only place that configures logging or draws progress bars.

Heavy modules (numba kernels, matplotlib) are imported inside the commands so that ``sensact --help``
stays instant.
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
