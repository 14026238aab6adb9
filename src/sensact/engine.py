"""Where a command's independent jobs run (docs/howto-fleet.md): here, one after another, or on a Dask cluster
(``dask.distributed``, the ``fleet`` extra), a LocalCluster on this machine's cores or a running
scheduler's workers. A job is a module-level function called with its arguments and ``progress``, a
``progress(description, done, total)`` callback that reaches the caller from whichever worker runs it.

Jobs are handed out largest first (their ``cost``): with five logs on two workers, the long ones start
first and the short ones fill in, instead of one worker running the last long log alone. A job's result
does not depend on where it ran: each is a pure function of its arguments (the seeds are arguments),
and Dask's workers run numpy on one thread, as they are spawned (``distributed.nanny.pre-spawn-environ``).
"""

from __future__ import annotations

import os
import time
import uuid
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any, Protocol

from sensact.errors import SensactError
from sensact.progress import Progress


@dataclass(frozen=True)
class Job:
    """One call of ``fn(*args, progress=...)``; ``name`` says which in progress and errors, ``cost`` orders them."""

    fn: Callable[..., Any]
    args: tuple[Any, ...]
    name: str
    cost: float = 1.0


def plain(fn: Callable[..., Any], args: tuple[Any, ...], *, progress: Progress | None = None) -> Any:
    """A job of a function that takes no ``progress``: ``Job(plain, (fn, args), name)``."""
    return fn(*args)


@dataclass(frozen=True)
class Failed:
    """A job that raised, as one line: ``bad_input`` when the input was at fault (a ``SensactError``), else
    an internal error (sensact's own, or a worker that died)."""

    error: str
    bad_input: bool


class JobFailed(SensactError):
    """A job of an engine that does not isolate failures raised; the message is its one line."""


# (job index, description, done, total) of a job's progress, and the job's index and outcome when it ends
OnProgress = Callable[[int, str, int, int | None], None]
OnDone = Callable[[int, Any], None]


class Engine(Protocol):
    workers: int  # how many jobs run at once
    where: str  # "this process", "a LocalCluster of 2 workers", "the cluster at tcp://..."

    def run(
        self,
        jobs: Sequence[Job],
        *,
        isolate: bool = False,
        on_progress: OnProgress | None = None,
        on_done: OnDone | None = None,
    ) -> list[Any]:
        """Each job's result, in the order given. With ``isolate``, a job that raised is its ``Failed`` and
        the others run on; without, the first failure is raised (``JobFailed`` on a cluster)."""
        ...


def untagged(progress: Progress | None) -> OnProgress | None:
    """A library ``progress(description, done, total)`` fed by every job (each job's description names it)."""
    if progress is None:
        return None
    return lambda i, desc, done, total: progress(desc, done, total)


def largest_first(jobs: Sequence[Job]) -> list[int]:
    """The order jobs start in: by cost, largest first, the given order among equals."""
    return sorted(range(len(jobs)), key=lambda i: -jobs[i].cost)


def failure(exc: BaseException) -> Failed:
    """An exception as one line: a ``SensactError``'s own, else ``internal error: ...``."""
    if isinstance(exc, SensactError):
        return Failed(str(exc), True)
    text = " ".join(str(exc).split()) or "(no message)"
    return Failed(f"internal error: {type(exc).__name__}: {text} (run it alone with --debug, and report it)", False)


class InProcess:
    """Every job here, one after another, largest first."""

    workers = 1
    where = "this process"

    def run(
        self,
        jobs: Sequence[Job],
        *,
        isolate: bool = False,
        on_progress: OnProgress | None = None,
        on_done: OnDone | None = None,
    ) -> list[Any]:
        results: list[Any] = [None] * len(jobs)
        for i in largest_first(jobs):
            job = jobs[i]
            progress = _Tagged(i, on_progress)
            if isolate:
                try:
                    results[i] = job.fn(*job.args, progress=progress)
                except Exception as exc:  # isolated: the job's failure is its result
                    results[i] = failure(exc)
            else:
                results[i] = job.fn(*job.args, progress=progress)
            if on_done is not None:
                on_done(i, results[i])
        return results


@dataclass(frozen=True)
class _Tagged:
    index: int
    to: OnProgress | None

    def __call__(self, desc: str, done: int, total: int | None) -> None:
        if self.to is not None:
            self.to(self.index, desc, done, total)


class _Publish:
    """A job's progress on a worker, sent to the client as a Dask event (at most four a second, and its end)."""

    def __init__(self, topic: str, index: int) -> None:
        self.topic, self.index, self.last = topic, index, 0.0

    def __call__(self, desc: str, done: int, total: int | None) -> None:
        now = time.monotonic()
        if now - self.last < 0.25 and (total is None or done < total):
            return
        self.last = now
        from distributed import get_worker

        get_worker().log_event(self.topic, [self.index, desc, int(done), None if total is None else int(total)])


def _guarded(fn: Callable[..., Any], args: tuple[Any, ...], topic: str, index: int) -> Any:
    """A job on a worker: its result, or its ``Failed`` (an exception object need not survive the trip back)."""
    try:
        return fn(*args, progress=_Publish(topic, index))
    except Exception as exc:  # every failure goes back to the client as one line
        return failure(exc)


class OnDask:
    """Jobs on a Dask cluster through ``client``, largest first, each given to the first worker thread free:
    no more are submitted than the cluster has threads, the next as one ends. (All at once, the scheduler
    queued a job behind a running one on one worker while the other worker stood idle: four MRCLAM robots
    on two workers took 59 s where their own times pack into 46.)"""

    def __init__(self, client: Any, where: str) -> None:
        self.client, self.where = client, where
        workers = client.scheduler_info(n_workers=-1)["workers"]
        self.workers = max(1, len(workers))
        self.slots = max(1, sum(int(w.get("nthreads", 1)) for w in workers.values()))

    def run(
        self,
        jobs: Sequence[Job],
        *,
        isolate: bool = False,
        on_progress: OnProgress | None = None,
        on_done: OnDone | None = None,
    ) -> list[Any]:
        from distributed import as_completed

        topic = f"sensact-progress-{uuid.uuid4().hex}"  # this run's, on a scheduler others may share
        if on_progress is not None:
            self.client.subscribe_topic(topic, lambda event: on_progress(*event[1]))
        order = iter(largest_first(jobs))
        futures: dict[Any, int] = {}

        def submit() -> Any:
            i = next(order, None)
            if i is None:
                return None
            job = jobs[i]
            fut = self.client.submit(_guarded, job.fn, job.args, topic, i, key=f"{job.name}-{uuid.uuid4().hex[:8]}")
            futures[fut] = i
            return fut

        running = as_completed([f for f in (submit() for _ in range(self.slots)) if f is not None])
        results: list[Any] = [None] * len(jobs)
        try:
            for fut in running:
                if (nxt := submit()) is not None:
                    running.add(nxt)
                i = futures[fut]
                try:
                    results[i] = fut.result()
                except Exception as exc:  # a worker that died under the job
                    results[i] = failure(exc)
                if isinstance(results[i], Failed) and not isolate:
                    raise JobFailed(f"{jobs[i].name}: {results[i].error}")
                if on_done is not None:
                    on_done(i, results[i])
        finally:
            for fut in futures:
                fut.cancel()
            if on_progress is not None:
                self.client.unsubscribe_topic(topic)
        return results


def missing_dask() -> SensactError:
    return SensactError(
        "running on a cluster needs dask.distributed, which is not installed.",
        fix="pip install 'sensact[fleet]'.",
    )


def check_engine(workers: int | None = None, scheduler: str | None = None) -> None:
    """What ``open_engine`` would refuse, refused before the work a command does first (a model written, then
    its error bars on a cluster that is not there): a count under one, a scheduler that does not answer."""
    _refuse_workers(workers)
    if scheduler is not None:
        with open_engine(workers, scheduler):
            pass


def _refuse_threads(threads: int | None) -> None:
    if threads is not None and not 1 <= threads <= (os.cpu_count() or 1):
        raise SensactError(
            f"--threads-per-worker {threads:,}: a worker's threads are 1 to this machine's {os.cpu_count()} cores.",
            field="--threads-per-worker",
            fix="give 1 (the default), or as many as the worker's share of the cores.",
        )


def _refuse_workers(workers: int | None) -> None:
    from sensact.limits import MAX_WORKERS

    if workers is not None and workers < 1:
        raise SensactError(f"--workers {workers}: at least one is needed.", field="--workers", fix="give 1 or more.")
    if workers is not None and workers > MAX_WORKERS:
        raise SensactError(
            f"--workers {workers:,} is over the limit of {MAX_WORKERS} processes on this machine.",
            field="--workers",
            fix=f"give at most one per core ({os.cpu_count()} here); a larger cluster is a --scheduler's "
            "(SENSACT_MAX_WORKERS raises the limit).",
        )


THREADS_ENV = "SENSACT_THREADS"  # a process's thread budget (limits.thread_budget), set to a worker's allocation


@contextmanager
def _thread_budget(threads: int | None) -> Iterator[None]:
    """This process's thread budget set to ``threads`` while the context lasts (None: left as it is)."""
    if threads is None:
        yield
        return
    before = os.environ.get(THREADS_ENV)
    os.environ[THREADS_ENV] = str(threads)
    try:
        yield
    finally:
        if before is None:
            os.environ.pop(THREADS_ENV, None)
        else:
            os.environ[THREADS_ENV] = before


def _size_threads(dask_worker: Any = None) -> int:
    """Run on each worker (``Client.run``): sensact's and numba's threads sized from the worker's own
    allocation (``dask worker --nthreads N``, a LocalCluster's threads_per_worker), not from the machine's
    cores it shares."""
    import numba

    threads = int(getattr(getattr(dask_worker, "state", dask_worker), "nthreads", None) or 1)
    os.environ[THREADS_ENV] = str(threads)
    numba.set_num_threads(max(1, min(threads, numba.config.NUMBA_NUM_THREADS)))
    return threads


@contextmanager
def _restored(saved: dict[str, str | None]) -> Iterator[None]:
    """This process's environment variables ``saved`` put back as they were when the context ends."""
    try:
        yield
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


SCHEDULER_WAIT_S = 10  # how long a --scheduler address may take to answer before it is refused


@contextmanager
def open_engine(
    workers: int | None = None, scheduler: str | None = None, threads_per_worker: int | None = None
) -> Iterator[Engine]:
    """The engine a command runs its jobs on: the cluster at ``scheduler`` (an address such as
    ``tcp://host:8786``), each worker's threads sized from its own allocation; else a LocalCluster of
    ``workers`` processes (this machine's cores when None) of ``threads_per_worker`` threads each (1 when
    None); or, with ``workers`` 1 and no scheduler, this process (no Dask needed), on that many threads."""
    _refuse_threads(threads_per_worker)
    if scheduler is None and workers == 1:
        with _thread_budget(threads_per_worker):
            yield InProcess()
        return
    try:
        from distributed import Client, LocalCluster
    except ImportError:
        raise missing_dask() from None
    import logging

    if scheduler is not None:
        try:
            client = Client(scheduler, timeout=f"{SCHEDULER_WAIT_S}s")
        except ValueError as exc:  # not an address at all: no port, an unknown protocol
            raise SensactError(
                f"--scheduler {scheduler!r} is not a scheduler's address ({exc}).",
                field="--scheduler",
                fix="give it as tcp://HOST:PORT (`dask scheduler` prints it, 8786 by default), or leave it out.",
            ) from None
        except (OSError, TimeoutError) as exc:
            raise SensactError(
                f"no Dask scheduler answered at {scheduler} ({exc}).",
                field="--scheduler",
                fix="start one (`dask scheduler`, and `dask worker ADDRESS` on each machine) or leave out --scheduler "
                "for a cluster on this machine.",
            ) from None
        with client:
            client.run(_size_threads)  # the workers there now; one that joins later keeps its cores' count
            yield OnDask(client, f"the cluster at {scheduler}")
        return
    _refuse_workers(workers)
    n = workers or os.cpu_count() or 1
    import dask

    # numpy on one thread a worker, as Dask spawns them; but not Dask's MALLOC_TRIM_THRESHOLD_: setting it turns
    # off glibc's adaptive mmap threshold, and EM's large temporaries are then mapped and faulted in afresh
    # each time (EM ran 1.5 times slower on a worker, its time in the kernel)
    t = threads_per_worker or 1
    names = ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", THREADS_ENV)
    threads = dict.fromkeys(names, t)  # numpy's and sensact's own threads: the worker's allocation (numba's below)
    # the nanny writes these into this process's environment too, and leaves them: put back when the cluster
    # closes (numba refuses a thread count other than the one its pool started with; sensact's own would stay 1)
    saved = {k: os.environ.get(k) for k in names}
    with (
        _restored(saved),
        dask.config.set({"distributed.nanny.pre-spawn-environ": threads}),
        LocalCluster(
            n_workers=n,
            threads_per_worker=t,
            processes=True,
            dashboard_address=None,
            silence_logs=logging.ERROR,
        ) as cluster,
        Client(cluster) as client,
    ):
        client.run(_size_threads)
        yield OnDask(client, f"a LocalCluster of {n} worker{'s' * (n > 1)}" + (f" of {t} threads" if t > 1 else ""))
