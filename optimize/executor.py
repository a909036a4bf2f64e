"""Where the per-actuator solves run: local worker processes by default, or a Dask distributed cluster.

Every stage hands its per-actuator tasks to :func:`map_tasks` (through :meth:`RunContext.map`): ``fn(ctx,
task)`` for each task, where ``fn`` is a module-level function and ``ctx`` the run's context, sent with the
task (it pickles; a few MB). Two executors implement the standard ``concurrent.futures`` interface
(``submit`` returning futures):

* :class:`LocalExecutor` (default): ``concurrent.futures.ProcessPoolExecutor`` on forked processes
  (``cfg.workers``; one task at a time in the run's own process when that is 1), one BLAS thread each;
* :class:`DaskExecutor` (``pamkin optimize --scheduler tcp://host:8786``): a ``dask.distributed`` client; the
  context is scattered to the workers once per stage call, the tasks run where the scheduler puts them.

The results do not depend on where a task runs or in which order the tasks finish: each task is solved on its
own, with one BLAS thread, and the results are put back in task order. Each finished task is handed to the
run's store (:mod:`optimize.store`) as it completes, so that a killed run resumes where it stopped.
"""

from __future__ import annotations

import concurrent.futures as cf
import contextlib
import multiprocessing as mp
import os
from collections.abc import Callable, Iterator

from pamkin.errors import ConfigurationError


@contextlib.contextmanager
def one_blas_thread() -> Iterator[None]:
    """Context in which BLAS runs on one thread: every solve does, in the workers and in the run's own process,
    so that the design does not depend on how many BLAS threads the machine would start (they change the
    summation order) and the workers do not oversubscribe the cores (idle OpenBLAS threads spin; measured, 4
    actuators on 2 workers of a 2-core machine: 224 -> 180 s wall, system time 101 -> 18 s). Two OpenBLAS
    copies are involved: numpy's, limited with threadpoolctl, and the one CasADi loads with IPOPT (MUMPS),
    which threadpoolctl does not find: it reads ``OPENBLAS_NUM_THREADS`` when it is loaded, so the variable
    is 1 inside the context (restored on exit; a copy loaded inside keeps one thread)."""
    from threadpoolctl import threadpool_limits  # noqa: PLC0415  (optional at import: only runs need it)

    before = os.environ.get("OPENBLAS_NUM_THREADS")
    os.environ["OPENBLAS_NUM_THREADS"] = "1"
    try:
        with threadpool_limits(limits=1, user_api="blas"):
            yield
    finally:
        if before is None:
            os.environ.pop("OPENBLAS_NUM_THREADS", None)
        else:
            os.environ["OPENBLAS_NUM_THREADS"] = before


def run_task(fn: Callable, ctx, task):
    """``fn(ctx, task)`` with one BLAS thread (what every worker runs)."""
    with one_blas_thread():
        return fn(ctx, task)


def _worker_start() -> None:
    """Process-pool initializer: the worker's BLAS on one thread for its whole life."""
    os.environ["OPENBLAS_NUM_THREADS"] = "1"
    from threadpoolctl import threadpool_limits  # noqa: PLC0415

    threadpool_limits(limits=1, user_api="blas")


class LocalExecutor:
    """Local worker processes (forked; ``workers`` of them; in-process when ``workers`` is 1)."""

    def __init__(self, workers: int = 2):
        if workers < 1:
            raise ConfigurationError(f"workers must be >= 1, got {workers}")
        self.workers = workers

    def map_unordered(self, fn: Callable, ctx, tasks: list) -> Iterator[tuple[int, object]]:
        """``(index, fn(ctx, tasks[index]))`` as each task finishes."""
        if self.workers == 1 or len(tasks) <= 1:
            for i, t in enumerate(tasks):
                yield i, run_task(fn, ctx, t)
            return
        with cf.ProcessPoolExecutor(min(self.workers, len(tasks)), mp_context=mp.get_context("fork"),
                                    initializer=_worker_start) as pool:
            futures = {pool.submit(fn, ctx, t): i for i, t in enumerate(tasks)}
            for f in cf.as_completed(futures):
                yield futures[f], f.result()

    def close(self) -> None:
        """Nothing to release (each stage call has its own pool)."""


class DaskExecutor:
    """A Dask distributed cluster: ``scheduler`` is its address (``tcp://host:8786``) or a ``Client``."""

    def __init__(self, scheduler):
        try:
            from distributed import Client  # noqa: PLC0415  (optional dependency: pip install pamkin[dask])
        except ImportError:
            raise ConfigurationError("--scheduler needs Dask distributed: pip install 'dask[distributed]'") from None
        if isinstance(scheduler, Client):
            self.client, self._own = scheduler, False
        else:
            try:
                self.client, self._own = Client(scheduler, timeout="20s"), True
            except OSError as e:
                raise ConfigurationError(f"--scheduler {scheduler}: cannot reach the Dask scheduler ({e})") from None

    def map_unordered(self, fn: Callable, ctx, tasks: list) -> Iterator[tuple[int, object]]:
        from distributed import as_completed  # noqa: PLC0415

        shared = self.client.scatter(ctx, broadcast=True)
        futures = {self.client.submit(run_task, fn, shared, t, pure=False): i for i, t in enumerate(tasks)}
        for f in as_completed(futures):
            yield futures[f], f.result()

    def close(self) -> None:
        if self._own:
            self.client.close()


def make_executor(workers: int, scheduler: str | None = None):
    """The executor of a run: Dask at ``scheduler`` where given, else ``workers`` local processes."""
    return DaskExecutor(scheduler) if scheduler else LocalExecutor(workers)


def default_workers() -> int:
    """Local worker processes by default: the cores, at most 2."""
    return max(1, min(2, os.cpu_count() or 1))


def map_tasks(ctx, fn: Callable, tasks: list, label: str, cost: list[float] | None = None) -> list:
    """``fn(ctx, task)`` over ``tasks`` on ``ctx.executor`` (local processes when it has none), returned in the
    order they finish (progress on ``ctx.stream``). With ``cost`` (an estimate of each task's time) the tasks
    are handed out longest first, so that no worker starts a long one while the others run out of work.
    Tasks the run's store (``ctx.store``) already holds under ``label`` are not run again: their stored
    results come first; every newly finished one is stored as it completes."""
    if cost is not None:
        tasks = [tasks[i] for i in sorted(range(len(tasks)), key=lambda i: (-cost[i], i))]
    store = ctx.store
    if store is not None:         # a stage may map more than once: each call has its own folder
        n = store.calls.get(label, 0)
        store.calls[label] = n + 1
        label = f"{label}-{n}"
    done: list = []
    todo: list = []
    for t in tasks:
        hit = store.load(label, t) if store is not None else None
        if hit is not None:
            done.append(hit)
        else:
            todo.append(t)
    for i, r in enumerate(done):
        progress_line(i + 1, len(tasks), r, ctx.stream, resumed=True)
    executor = ctx.executor or LocalExecutor(ctx.cfg.workers)
    out = list(done)
    for i, r in executor.map_unordered(fn, ctx, todo) if todo else ():     # all stored: no workers to start
        if store is not None:
            store.save(label, todo[i], r)
        out.append(r)
        progress_line(len(out), len(tasks), r, ctx.stream)
    return out


def progress_line(done: int, total: int, r, stream, resumed: bool = False) -> None:
    """One progress line of a stage's tasks on ``stream`` (``resumed``: taken from the run folder's store)."""
    if stream is None:
        return
    bar = "#" * int(30 * done / total)
    e = next(iter(r.nrmse_samples.values()), float("nan"))
    print(f"solve [{bar:30s}] {done:2d}/{total}  {r.id:2d} {r.name:26s} {'ok  ' if r.success else 'FAIL'} "
          f"fit NRMSE {e:.3f} ({r.seconds:.1f} s{', resumed' if resumed else ''})", file=stream, flush=True)
