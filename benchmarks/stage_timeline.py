"""Where the cores wait in a diagnosis: each stage's wall time, this process's CPU and its
worker processes' CPU, sampled while ``diagnose`` runs (``bench_diagnose.py --timeline``).

With ``--workers 2`` a stage where this process works alone leaves the workers idle, and a
stage on the workers leaves this process waiting; the idle core-seconds of a stage are the
cores times its wall time less the CPU spent in it. On a shared machine the wall time is the
other jobs'; the CPU columns are what a quiet machine would spend.

A thread samples the CPU (user + system) of this process and of each of its descendants
(``psutil``; a worker's CPU is counted by its increments, so one that exits takes nothing
back, and what it spent after its last sample, at most one period, is not counted) every
:data:`PERIOD_S` and at each stage's start and end, and each interval goes to the stage
running at its start: the
innermost of ``diagnose``'s parts wrapped by :func:`label_stages` (this process's main
thread only: what another thread runs beside it, the restoring-force evidence with workers,
goes to the main thread's stage; the workers run their tasks unwrapped).
"""

from __future__ import annotations

import functools
import os
import threading
import time
from collections.abc import Callable
from typing import Any

#: Seconds between samples.
PERIOD_S = 0.2


class StageTimeline:
    """Samples of (time, stage, this process's CPU, the workers' CPU so far)."""

    def __init__(self) -> None:
        import psutil

        self._me = psutil.Process()
        self._error = psutil.Error
        self.stack = ["outside the stages"]
        self.samples: list[tuple[float, str, float, float]] = []
        self._kids: dict[int, float] = {}
        self._kids_total = 0.0
        self._stop = threading.Event()
        self._lock = threading.Lock()  # the sampler thread and the stages' edges both sample
        self._thread = threading.Thread(target=self._run, daemon=True)

    def _cpu_now(self) -> tuple[float, float]:
        t = self._me.cpu_times()
        for child in self._me.children(recursive=True):
            try:
                c = child.cpu_times()
            except self._error:  # gone between the listing and the reading
                continue
            now = c.user + c.system
            self._kids_total += max(0.0, now - self._kids.get(child.pid, 0.0))
            self._kids[child.pid] = now
        return t.user + t.system, self._kids_total

    def _sample(self) -> None:
        with self._lock:
            self._sample_unlocked()

    def _sample_unlocked(self) -> None:
        own, kids = self._cpu_now()
        self.samples.append((time.perf_counter(), self.stack[-1], own, kids))

    def _run(self) -> None:
        while not self._stop.is_set():
            self._sample()
            self._stop.wait(PERIOD_S)

    def __enter__(self) -> StageTimeline:
        self._sample()
        self._thread.start()
        return self

    def __exit__(self, *exc: Any) -> None:
        self._stop.set()
        self._thread.join()
        self._sample()

    def label(self, owner: Any, name: str, label: Callable[..., str]) -> None:
        """Wrap ``owner.name`` so that the time inside it goes to ``label(*args)``."""
        fn = getattr(owner, name)

        @functools.wraps(fn)
        def inner(*a: Any, **k: Any) -> Any:
            if threading.current_thread() is not threading.main_thread():
                return fn(*a, **k)  # work beside the main thread's stage belongs to it
            # a sample at each edge: a stage that holds the interpreter (a pure-Python loop)
            # can keep the sampler thread from running until it ends
            # (under the lock, so no stage begins or ends inside a sample; each edge's sample
            # is the first of the stage that starts there)
            name = label(*a, **k)
            with self._lock:
                self.stack.append(name)
                self._sample_unlocked()
            try:
                return fn(*a, **k)
            finally:
                with self._lock:
                    self.stack.pop()
                    self._sample_unlocked()

        setattr(owner, name, inner)

    def stages(self) -> list[tuple[str, float, float, float]]:
        """Per stage, in order of first appearance: wall seconds, this process's CPU
        seconds, the workers' CPU seconds."""
        out: dict[str, list[float]] = {}
        for (t0, stage, p0, k0), (t1, _, p1, k1) in zip(
            self.samples, self.samples[1:], strict=False
        ):
            acc = out.setdefault(stage, [0.0, 0.0, 0.0])
            acc[0] += t1 - t0
            acc[1] += p1 - p0
            acc[2] += k1 - k0
        return [(s, *v) for s, v in out.items()]

    def table(self) -> str:
        """The stages as a markdown table with the idle core-seconds of this machine's
        cores (those this process may run on)."""
        cores = len(os.sched_getaffinity(0))
        lines = [
            f"| stage | wall s | this process, CPU s | workers, CPU s | idle core-s ({cores}) |",
            "|---|---|---|---|---|",
        ]
        total = [0.0, 0.0, 0.0]
        for stage, wall, own, kids in self.stages():
            total = [total[0] + wall, total[1] + own, total[2] + kids]
            lines.append(f"| {stage} | {wall:.1f} | {own:.1f} | {kids:.1f} | "
                         f"{cores * wall - own - kids:.1f} |")  # fmt: skip
        wall, own, kids = total
        lines.append(f"| **total** | {wall:.1f} | {own:.1f} | {kids:.1f} | "
                     f"{cores * wall - own - kids:.1f} |")  # fmt: skip
        return "\n".join(lines)


def label_stages(timeline: StageTimeline) -> None:
    """Label ``diagnose``'s parts (this process): the preparation, the evidence, each
    profile of the nuisances, each batch of fits, each joint refit (step, refit after the
    nuisances moved, polish) and its global stage and Nelder-Mead, the verdict."""
    from stiffnet.measurement import diagnose, fitting

    def within(what: str) -> Callable[..., str]:
        return lambda *a, **k: f"{what} [{timeline.stack[-1]}]"

    timeline.label(diagnose, "_prepare", lambda *a, **k: "rows, statistics, floors")
    # by the function's own name: as a quoted string it reads as the diagnosis JSON's earlier key
    evidence = diagnose.restoring_force_evidence.__name__
    timeline.label(diagnose, evidence, lambda *a, **k: "evidence")
    # with workers the evidence is read on a thread beside the nuisances (unlabelled there):
    # this is the wait for the rest of it, the early single fits running beside it
    timeline.label(diagnose, "_await_evidence", lambda *a, **k: "evidence (the rest)")
    timeline.label(diagnose, "profile_nuisances", within("nuisances"))
    timeline.label(diagnose._Run, "fits", lambda run, cands, *a, **k:
                   f"fits: {run.stage.split(',')[0]} ({len(cands)})")  # fmt: skip
    timeline.label(diagnose, "_joint_step", lambda *a, **k: "joint step")
    timeline.label(diagnose, "_accept", lambda *a, **k: "refit after the nuisances")
    timeline.label(diagnose, "_polish", lambda *a, **k: "polish")
    timeline.label(diagnose, "_conclude", lambda *a, **k: "verdict")
    timeline.label(diagnose, "fit_joint", lambda target, names, *a, **k:
                   f"joint refit {'+'.join(names)} [{timeline.stack[-1]}]")  # fmt: skip
    timeline.label(fitting, "global_stage", lambda *a, **k: f"{timeline.stack[-1]}, global")
    timeline.label(fitting, "_nelder_mead", lambda *a, **k: f"{timeline.stack[-1]}, Nelder-Mead")
