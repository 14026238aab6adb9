"""One line on stderr while numba compiles sensact's kernels, which it does once per install.

numba keeps what it compiles in a cache beside the package (or, where that folder is read-only, in the
user's cache folder, or ``NUMBA_CACHE_DIR``) and fires its ``numba:compile`` event only when a kernel is
not found there. The first run after an install compiles for tens of seconds of CPU with nothing else to
show; without a word it looks like a hang.
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

from numba.core import event

MESSAGE = (
    "compiling sensact's numba kernels: once per install (tens of seconds); later runs load them from numba's cache"
)


class CompileNotice(event.Listener):
    """A numba event listener that says ``MESSAGE`` once, when the first kernel starts compiling, and
    counts the kernels compiled (a nested compile is counted in its caller's)."""

    def __init__(self, say: Callable[[str], None]) -> None:
        self._say = say
        self._depth = 0
        self.announced = False
        self.kernels = 0

    def on_start(self, event: Any) -> None:
        if self._depth == 0 and not self.announced:
            self._say(MESSAGE)
            self.announced = True
        self._depth += 1

    def on_end(self, event: Any) -> None:
        self._depth -= 1
        if self._depth == 0:
            self.kernels += 1


@contextmanager
def announce_compiles(say: Callable[[str], None] | None = None) -> Iterator[CompileNotice]:
    """While inside, say ``MESSAGE`` once if numba compiles anything (on stderr unless ``say`` is given)."""
    notice = CompileNotice(say or (lambda line: print(line, file=sys.stderr, flush=True)))
    event.register("numba:compile", notice)
    try:
        yield notice
    finally:
        event.unregister("numba:compile", notice)
