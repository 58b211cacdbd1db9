"""Run independent tasks in-process or on Dask, in order, with retries and a report."""

from __future__ import annotations

import contextlib
import functools
import uuid
from collections.abc import Callable, Iterable, Sequence
from contextlib import AbstractContextManager
from dataclasses import dataclass, field
from typing import Any

from stiffnet.distributed.cluster import dask_client
from stiffnet.errors import StiffnetError


@dataclass
class TaskReport:
    """What a :func:`run_tasks` call did.

    Attributes
    ----------
    results
        One result per item, in the items' order (``None`` where the task failed).
    names
        The task names, in the items' order.
    failed
        Name → one-line error, for tasks that failed after their retries.
    rerun
        Name → number of extra runs, for tasks the cluster ran more than once (an
        exception retried, or a worker lost while running it).
    backend
        ``"in-process"`` or the scheduler address.
    errors
        Name → the exception of each failed task (for tracebacks).
    """

    results: list[Any]
    names: list[str]
    failed: dict[str, str] = field(default_factory=dict)
    rerun: dict[str, int] = field(default_factory=dict)
    backend: str = "in-process"
    errors: dict[str, BaseException] = field(default_factory=dict, repr=False)

    def raise_failures(self) -> None:
        """Raise one :class:`StiffnetError` naming the failed tasks, if any."""
        if not self.failed:
            return
        first, msg = next(iter(self.failed.items()))
        more = len(self.failed) - 1
        others = f" (and {more} more: {', '.join(list(self.failed)[1:6])})" if more else ""
        raise StiffnetError(f"task {first} failed: {msg}{others}") from self.errors.get(first)


def _label(fn: Any) -> str:
    while isinstance(fn, functools.partial):
        fn = fn.func
    return getattr(fn, "__name__", "task")


def _describe(exc: BaseException) -> str:
    """One line: a user error's own message, else the exception type and first line."""
    text = str(exc).strip().splitlines()
    first = text[0] if text else ""
    if isinstance(exc, StiffnetError):
        return first
    return f"{type(exc).__name__}: {first}" if first else type(exc).__name__


@dataclass
class _UserError:
    """A task's :class:`StiffnetError`, returned rather than raised: bad input fails the
    same way every time, so Dask must not retry it."""

    error: StiffnetError


#: A thread limit: ``limit(n)`` is a context manager running its block on at most ``n``
#: threads of the task's compute library (e.g. ``stiffnet.simulator.compiled.limited_threads``).
ThreadLimit = Callable[[int], AbstractContextManager[Any]]


def _run_on_worker(fn: Callable[[Any], Any], item: Any, thread_limit: ThreadLimit | None) -> Any:
    """Run ``fn(item)`` on a worker, on one compute thread (a worker is one core)."""
    try:
        with thread_limit(1) if thread_limit is not None else contextlib.nullcontext():
            return fn(item)
    except StiffnetError as exc:
        return _UserError(exc)


def run_tasks(
    fn: Callable[[Any], Any],
    items: Iterable[Any],
    *,
    scheduler: str | None = None,
    workers: int | None = None,
    retries: int = 2,
    progress: Callable[[int, int], None] | None = None,
    names: Sequence[str] | None = None,
    client: Any = None,
    thread_limit: ThreadLimit | None = None,
) -> TaskReport:
    """Run ``fn`` on every item and report results, failures and re-runs.

    Unlike :func:`map_tasks` this never raises for a failed task; see
    :meth:`TaskReport.raise_failures`. In-process, tasks run in order and the first
    failure stops the run (the remaining items are not tried). On Dask, every task
    runs to completion or failure, so an interrupted job loses as little as possible.

    Parameters
    ----------
    fn
        A picklable function of one item (module-level, so workers can import it).
    items
        The tasks' arguments.
    scheduler, workers
        Where to run, as in :func:`stiffnet.distributed.cluster.dask_client`.
    retries
        Extra attempts of a task that raised (Dask ``retries=``), except for a
        :class:`StiffnetError` (bad input fails again: reported at once). A worker lost
        while running a task is handled by the scheduler (the task is rescheduled).
    progress
        Called as ``progress(done, total)`` as tasks finish.
    names
        Task names for reports (default ``fn-name[i]``).
    client
        An existing ``distributed.Client`` to use instead of ``scheduler``/``workers``.
    thread_limit
        On Dask, each task runs inside ``thread_limit(1)``: a worker process is one core,
        and a task's own thread pool (numba's, for the simulator) would oversubscribe it
        on a cluster whose workers were not started with one thread. In-process tasks
        keep every thread. The callers pass the limit of the library they compute with;
        this module imports none of them.
    """
    items = list(items)
    label = _label(fn)
    names = list(names) if names is not None else [f"{label}[{i}]" for i in range(len(items))]
    if len(names) != len(items):
        raise ValueError("names and items differ in length")
    if client is not None:
        return _run_dask(client, fn, items, names, retries, progress, thread_limit)
    with dask_client(scheduler, workers) as c:
        if c is None:
            return _run_local(fn, items, names, progress)
        return _run_dask(c, fn, items, names, retries, progress, thread_limit)


def map_tasks(
    fn: Callable[[Any], Any],
    items: Iterable[Any],
    *,
    scheduler: str | None = None,
    workers: int | None = None,
    retries: int = 2,
    progress: Callable[[int, int], None] | None = None,
    names: Sequence[str] | None = None,
    thread_limit: ThreadLimit | None = None,
) -> list[Any]:
    """``[fn(x) for x in items]``, in-process or on Dask, in the items' order.

    Runs in-process when ``scheduler`` and ``workers`` are both ``None``; on the Dask
    scheduler at ``scheduler``; or on a LocalCluster of ``workers`` single-threaded
    processes started for the call. A task that raises is retried ``retries`` times
    (not for a :class:`StiffnetError`: bad input); one that still fails raises a
    one-line :class:`StiffnetError` naming it (after the other tasks finished, on Dask).
    ``thread_limit``: see :func:`run_tasks`.

    Examples
    --------
    >>> map_tasks(abs, [-1, 2, -3])
    [1, 2, 3]
    """
    report = run_tasks(fn, items, scheduler=scheduler, workers=workers, retries=retries,
                       progress=progress, names=names, thread_limit=thread_limit)  # fmt: skip
    report.raise_failures()
    return report.results


def _run_local(fn, items, names, progress) -> TaskReport:
    report = TaskReport(results=[None] * len(items), names=names)
    for i, item in enumerate(items):
        try:
            report.results[i] = fn(item)
        except Exception as exc:  # noqa: BLE001 - reported with the task's name
            report.failed[names[i]] = _describe(exc)
            report.errors[names[i]] = exc
            return report
        if progress:
            progress(i + 1, len(items))
    return report


def _run_dask(client, fn, items, names, retries, progress, thread_limit) -> TaskReport:
    pending = submit_tasks(fn, items, client=client, names=names, retries=retries,
                           thread_limit=thread_limit)  # fmt: skip
    return pending.collect(progress)


@dataclass
class PendingTasks:
    """Tasks submitted to a Dask cluster by :func:`submit_tasks`, not yet collected."""

    client: Any
    futures: list[Any]
    names: list[str]

    def collect(self, progress: Callable[[int, int], None] | None = None) -> TaskReport:
        """Wait for every task and report as :func:`run_tasks` does (``progress(done,
        total)`` as they finish); the results are then released on the workers."""
        from distributed import as_completed

        client, futures, names = self.client, self.futures, self.names
        report = TaskReport(results=[None] * len(futures), names=names,
                            backend=str(client.scheduler.address))  # fmt: skip
        index = {f.key: i for i, f in enumerate(futures)}
        done = 0
        for future in as_completed(futures):
            i = index[future.key]
            if future.status == "finished":
                result = future.result()
                if isinstance(result, _UserError):
                    report.failed[names[i]] = _describe(result.error)
                    report.errors[names[i]] = result.error
                else:
                    report.results[i] = result
            elif future.status == "error":
                exc = future.exception()
                report.failed[names[i]] = _describe(exc)
                report.errors[names[i]] = exc
            else:  # cancelled: the scheduler or this client went away
                report.failed[names[i]] = f"task {future.status} (the Dask scheduler was lost?)"
            done += 1
            if progress:
                progress(done, len(futures))
        keys = [f.key for f in futures]
        extra = {names[index[k]]: n for k, n in _extra_runs(client, keys).items()}
        report.rerun = {n: extra[n] for n in names if n in extra}  # in the items' order
        report.failed = {n: report.failed[n] for n in names if n in report.failed}
        for name, exc in report.errors.items():  # say how hard the cluster tried
            if not isinstance(exc, StiffnetError):
                report.failed[name] += f" (after {1 + report.rerun.get(name, 0)} runs)"
        client.cancel(futures)  # release results held on the workers
        return report


def submit_tasks(
    fn: Callable[[Any], Any],
    items: Iterable[Any],
    *,
    client: Any,
    names: Sequence[str] | None = None,
    retries: int = 2,
    thread_limit: ThreadLimit | None = None,
    priority: int = 0,
) -> PendingTasks:
    """Submit ``fn`` on every item to the Dask ``client`` and return at once; the tasks run
    while the caller does other work, and :meth:`PendingTasks.collect` waits for them.

    ``priority``: Dask's (higher first; :func:`run_tasks`' tasks have 0): tasks submitted
    below 0 take a worker only when no task of a higher priority is waiting, so they fill
    the cores other work leaves idle. The other arguments as in :func:`run_tasks`.
    """
    items = list(items)
    label = _label(fn)  # Dask groups tasks by this prefix (dashboard, logs)
    names = list(names) if names is not None else [f"{label}[{i}]" for i in range(len(items))]
    if len(names) != len(items):
        raise ValueError("names and items differ in length")
    run_id = uuid.uuid4().hex[:8]
    keys = [f"{label}-{run_id}-{i}" for i in range(len(items))]
    futures = client.map(_run_on_worker, [fn] * len(items), items,
                         [thread_limit] * len(items), key=keys, retries=retries,
                         pure=False, priority=priority)  # fmt: skip
    return PendingTasks(client, list(futures), names)


def _extra_runs(client, keys: list[str]) -> dict[str, int]:
    """Keys the scheduler sent to a worker more than once, from its transition log."""
    try:
        story = client.run_on_scheduler(_processing_counts, keys=keys)
    except Exception:  # noqa: BLE001 - the report is best effort, the results are not
        return {}
    return {k: n - 1 for k, n in story.items() if n > 1}


def _processing_counts(keys: list[str], dask_scheduler: Any = None) -> dict[str, int]:
    counts = dict.fromkeys(keys, 0)
    for entry in dask_scheduler.story(*keys):
        key, finish = entry[0], entry[2]
        if key in counts and finish == "processing":
            counts[key] += 1
    return counts
