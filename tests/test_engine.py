"""sensact.engine: jobs here or on a Dask LocalCluster of 2 workers, with the same results, largest first,
each failure isolated as one line, and progress from the workers."""

from __future__ import annotations

import sys
import threading

import pytest

from sensact.engine import Failed, InProcess, Job, JobFailed, largest_first, open_engine
from sensact.errors import LogFormatError


def square(x: float, *, progress=None) -> float:
    if progress is not None:
        progress(f"squaring {x}", 1, 1)
    return x * x


def refuse(x: float, *, progress=None) -> float:
    raise LogFormatError(f"row {x} is bad.", file="actions.csv", field="t_s", fix="sort the rows.")


def crash(x: float, *, progress=None) -> float:
    return [][int(x)]


@pytest.fixture(scope="module")
def cluster():
    """One LocalCluster of 2 workers for the module; the jobs above travel by value (tests/ is not on the
    workers' path)."""
    pytest.importorskip("distributed", reason="the fleet extra (dask.distributed) comes with the test extra")
    import cloudpickle

    cloudpickle.register_pickle_by_value(sys.modules[__name__])
    with open_engine(workers=2) as engine:
        yield engine


def test_jobs_start_largest_first_and_come_back_in_the_order_given():
    jobs = [Job(square, (float(k),), f"j{k}", cost=c) for k, c in enumerate([1.0, 5.0, 3.0, 5.0])]
    assert largest_first(jobs) == [1, 3, 2, 0]
    started = []
    out = InProcess().run(jobs, on_progress=lambda i, desc, done, total: started.append(i))
    assert out == [0.0, 1.0, 4.0, 9.0]
    assert started == [1, 3, 2, 0]


def test_in_process_isolates_each_failure_as_one_line():
    jobs = [Job(square, (2.0,), "a"), Job(refuse, (3.0,), "b"), Job(crash, (1.0,), "c")]
    done = {}
    out = InProcess().run(jobs, isolate=True, on_done=lambda i, o: done.setdefault(i, o))
    assert out[0] == 4.0
    assert out[1] == Failed("actions.csv: t_s: row 3.0 is bad. Fix: sort the rows.", True)
    assert isinstance(out[2], Failed) and not out[2].bad_input
    assert out[2].error.startswith("internal error: IndexError: list index out of range")
    assert "\n" not in out[2].error
    assert done == dict(enumerate(out))
    with pytest.raises(LogFormatError):  # not isolated: the first failure is raised as it is
        InProcess().run(jobs)


def test_one_worker_needs_no_dask(monkeypatch):
    monkeypatch.setitem(sys.modules, "distributed", None)  # as if the fleet extra were not installed
    with open_engine(workers=1) as engine:
        assert isinstance(engine, InProcess)
    with pytest.raises(Exception, match=r"pip install 'sensact\[fleet\]'"), open_engine(workers=2):
        pass


def test_zero_workers_is_one_line():
    pytest.importorskip("distributed")
    with pytest.raises(Exception, match="--workers 0: at least one is needed"), open_engine(workers=0):
        pass


def test_a_cluster_gives_what_this_process_gives(cluster):
    jobs = [Job(square, (float(k),), f"j{k}", cost=float(k % 3)) for k in range(7)]
    heard, lock = {}, threading.Lock()

    def on_progress(i, desc, done, total):
        with lock:
            heard[i] = desc

    assert cluster.workers == 2 and cluster.where == "a LocalCluster of 2 workers"
    assert cluster.run(jobs, on_progress=on_progress) == InProcess().run(jobs)
    # progress travels as events through the scheduler: wait for the last to arrive
    for _ in range(100):
        if len(heard) == len(jobs):
            break
        threading.Event().wait(0.05)
    assert heard == {k: f"squaring {float(k)}" for k in range(7)}


def test_a_cluster_isolates_failures_and_raises_them_when_asked(cluster):
    jobs = [Job(square, (2.0,), "a"), Job(refuse, (3.0,), "b"), Job(crash, (1.0,), "c")]
    out = cluster.run(jobs, isolate=True)
    assert out == InProcess().run(jobs, isolate=True)
    with pytest.raises(JobFailed, match=r"^b: actions.csv: t_s: row 3.0 is bad"):
        cluster.run(jobs[:2])


def test_an_address_no_scheduler_answers_at_is_one_line(monkeypatch):
    pytest.importorskip("distributed")
    monkeypatch.setattr("sensact.engine.SCHEDULER_WAIT_S", 1)  # nothing listens there: no need to wait 10 s
    with (
        pytest.raises(Exception, match=r"no Dask scheduler answered at tcp://127\.0\.0\.1:9"),
        open_engine(scheduler="tcp://127.0.0.1:9"),
    ):
        pass


def budget(x: float, *, progress=None) -> int:
    from sensact.limits import thread_budget

    return thread_budget()


def test_a_worker_sizes_its_threads_from_its_allocation(cluster, monkeypatch):
    """Issue 94: the start race's threads follow SENSACT_THREADS, which the engine sets to each worker's
    threads (1 on a LocalCluster by default), and to --threads-per-worker in this process while it runs."""
    import os

    from sensact.errors import SensactError

    assert cluster.run([Job(budget, (0.0,), "a"), Job(budget, (1.0,), "b")]) == [1, 1]
    # the nanny writes the workers' thread counts into this process's environment too: put back on closing
    # (numba refused to run here after a fleet: its pool had started with another count)
    names = ("SENSACT_THREADS", "NUMBA_NUM_THREADS", "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS")
    before = {k: os.environ.get(k) for k in names}
    with open_engine(2, None, threads_per_worker=1) as two:
        assert two.run([Job(budget, (0.0,), "a")]) == [1]
    assert {k: os.environ.get(k) for k in names} == before
    monkeypatch.delenv("SENSACT_THREADS", raising=False)
    with open_engine(1, None, threads_per_worker=1) as here:
        assert here.run([Job(budget, (0.0,), "a")]) == [1]
    assert "SENSACT_THREADS" not in os.environ and budget(0.0) == (os.cpu_count() or 1)
    for bad in (0, 10_000):
        with pytest.raises(SensactError, match="--threads-per-worker"), open_engine(1, None, threads_per_worker=bad):
            pass
