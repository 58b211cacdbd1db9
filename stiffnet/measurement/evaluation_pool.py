"""Independent objective evaluations of this process's searches, spread over the workers.

A diagnosis runs its single and conditional fits as tasks on the workers, but the joint
refits, their block descent and the polish run here, one evaluation after the other, while
the workers wait. Many of those evaluations do not depend on each other: a fit's initial
design, each block of its global stage, a Nelder-Mead's first simplex, the initial states
of the nuisances' profile. Inside :func:`evaluation_pool` (a Dask client) such a batch is
cut into one chunk per worker and the chunks run as tasks
(:func:`stiffnet.distributed.tasks.run_tasks`); outside it, or for a batch too small to
pay for the round trip, they run here in order.

The numbers are the same either way: each evaluation is
:meth:`~stiffnet.measurement.target.CampaignTarget.per_recording` of the same target,
deterministic (common random numbers; one simulated batch per call wherever it runs), and
the results join the target's memo (:attr:`~stiffnet.measurement.target.CampaignTarget.known`)
as if they had been computed here. Only where the CPU is spent changes.
"""

from __future__ import annotations

import contextlib
import dataclasses
from collections.abc import Iterator, Sequence
from contextvars import ContextVar
from typing import Any

import numpy as np

from stiffnet.campaign.simulate import CampaignSolverSettings as SolverSettings
from stiffnet.effects.base import Effect
from stiffnet.measurement.statistics import SignalStatistics
from stiffnet.measurement.target import MEMO_ENTRIES, CampaignTarget
from stiffnet.simulator.motion_cache import reuse_motion

#: A batch of fewer evaluations than this runs here (a task's round trip, ~11 ms, and the
#: target's pickling are not paid back by splitting two evaluations).
MIN_BATCH = 3

_CLIENT: ContextVar[Any] = ContextVar("stiffnet_evaluation_pool", default=None)


@contextlib.contextmanager
def evaluation_pool(client: Any) -> Iterator[None]:
    """Inside the block, :func:`per_recording_many` and :func:`statistics_many` spread their
    batches over ``client``'s workers (None: in-process, as outside the block)."""
    token = _CLIENT.set(client)
    try:
        yield
    finally:
        _CLIENT.reset(token)


#: One evaluation: the model's effects, the settings and the keyword arguments of
#: :meth:`CampaignTarget.per_recording` (``rows``, ``starts``, ``inclination``, ``oversample``).
Call = tuple[Sequence[Effect], SolverSettings, dict[str, Any]]


def _chunk_per_recording(item: tuple[CampaignTarget, list[Call]]) -> list[np.ndarray]:
    target, calls = item
    # a measurement effect's points share their motion, as inside the fit that sent them
    with reuse_motion():
        return [target.per_recording(list(e), s, **kw) for e, s, kw in calls]


def _chunk_statistics(
    item: tuple[CampaignTarget, list[Call]],
) -> list[list[SignalStatistics | None]]:
    target, calls = item
    with reuse_motion():
        return [target.simulated_statistics(list(e), s, **kw) for e, s, kw in calls]


def _workers(client: Any) -> int:
    return max(1, sum(client.nthreads().values()))


def _spread(fn: Any, target: CampaignTarget, calls: list[Call], client: Any) -> list[Any]:
    """``calls`` in one contiguous chunk per worker, as tasks; results in the calls' order."""
    from stiffnet.distributed.tasks import run_tasks
    from stiffnet.simulator.compiled import limited_threads

    # the target without its memo (it can hold thousands of results the chunk never reads)
    light = dataclasses.replace(target)
    bounds = np.linspace(0, len(calls), min(_workers(client), len(calls)) + 1).round()
    chunks = [calls[int(a) : int(b)] for a, b in zip(bounds, bounds[1:], strict=False)]
    report = run_tasks(fn, [(light, c) for c in chunks], client=client,
                       thread_limit=limited_threads)  # fmt: skip
    report.raise_failures()
    return [r for chunk in report.results for r in chunk]


def per_recording_many(target: CampaignTarget, calls: Sequence[Call]) -> list[np.ndarray]:
    """``[target.per_recording(effects, settings, **kw) for effects, settings, kw in calls]``,
    the evaluations not in the target's memo spread over the pool's workers (see the module
    notes); the same arrays, and the same memo afterwards, as the loop."""
    calls = list(calls)
    client = _CLIENT.get()
    todo: list[int] = []
    # a stand-in target (a test's, a user's) is evaluated here: only a CampaignTarget travels
    if client is not None and len(calls) >= MIN_BATCH and isinstance(target, CampaignTarget):
        keys = [target.call_key(e, s, **kw) for e, s, kw in calls]
        # an effect pickle cannot digest (no memo key) cannot travel either: all here
        if all(k is not None for k in keys):
            todo = [i for i, k in enumerate(keys) if k not in target.known]
    if len(todo) < MIN_BATCH:
        return [target.per_recording(e, s, **kw) for e, s, kw in calls]
    done = dict(zip(todo, _spread(_chunk_per_recording, target, [calls[i] for i in todo],
                                  client), strict=True))  # fmt: skip
    for i, per in done.items():
        if len(target.known) < MEMO_ENTRIES:
            target.known[keys[i]] = per.copy()
    return [
        done[i].copy() if i in done else target.known[keys[i]].copy() for i in range(len(calls))
    ]


def statistics_many(
    target: CampaignTarget, calls: Sequence[Call]
) -> list[list[SignalStatistics | None]]:
    """``[target.simulated_statistics(effects, settings, **kw) for ...]`` spread over the
    pool's workers (see the module notes; in-process outside a pool)."""
    calls = list(calls)
    client = _CLIENT.get()
    if client is None or len(calls) < MIN_BATCH or not isinstance(target, CampaignTarget):
        return [target.simulated_statistics(e, s, **kw) for e, s, kw in calls]
    return _spread(_chunk_statistics, target, calls, client)


def map_independent(fn: Any, items: Sequence[Any]) -> list[Any]:
    """``[fn(item) for item in items]``, one task per item on the pool's workers (in order,
    here, outside a pool or for a single item): for a search whose independent steps are
    whole simulated batches (the face's screens and sweeps,
    :mod:`~stiffnet.measurement.face_by_simulation`) rather than evaluations of one target.
    ``fn`` is module-level (the workers import it); the items travel pickled, a target
    without its memo where the caller gives one so."""
    items = list(items)
    client = _CLIENT.get()
    if client is None or len(items) < 2:
        return [fn(item) for item in items]
    from stiffnet.distributed.tasks import run_tasks
    from stiffnet.simulator.compiled import limited_threads

    report = run_tasks(fn, items, client=client, thread_limit=limited_threads)
    report.raise_failures()
    return list(report.results)


__all__ = ["MIN_BATCH", "evaluation_pool", "map_independent", "per_recording_many",
           "statistics_many"]  # fmt: skip
