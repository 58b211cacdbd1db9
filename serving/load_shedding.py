"""Load shedding: what a lane's predictions cost and what it holds, priced before a job queues.

:class:`LaneCost` learns each lane's wall seconds per sample from its finished predictions
and models the wait for a worker the way the thread pool serves its queue;
:class:`Contention` is a lane's slow-down now (wall over CPU time of its recent jobs). The
server's admission (:class:`serving.app.Admission`) refuses with 429 and ``Retry-After``
a job whose expected finish passes :data:`SHED_MARGIN` of its timeout, before any work:
a 504 comes after all the work, a refusal before any.
"""

from __future__ import annotations

import heapq
import itertools
import math
import os
import threading
import time

#: Seconds per sample a lane assumes until its first prediction is measured: three to
#: seven times a quiet core's cost (a 5 s JSON of 5,000 samples ~0.15 s; a 2 M-sample upload
#: at 50 kHz ~6 s, 25 s at load 10 on 2 cores), so that the first queued jobs are refused
#: early rather than late.
SEED_S_PER_SAMPLE = {"small": 1e-4, "large": 2e-5}
#: Weight of the newest measurement in a lane's running mean of seconds per sample: a few
#: jobs follow a change of the machine's load, one slow job does not take over.
COST_EWMA = 0.3
#: Fraction of ``timeout_s`` a job's expected finish may reach: the costs are estimates (the
#: same 2 M-sample upload took 14.6-16.4 s at load 6.5), and a job that overruns is a 504
#: after all its work while a refusal is a 429 before any.
SHED_MARGIN = 0.8
#: Share of a running job's estimate still expected once it has overrun the estimate (it
#: is running: something remains).
OVERRUN_LEFT = 0.1
#: CPU seconds per sample a lane assumes until one is measured (a quiet core's cost).
SEED_CPU_S_PER_SAMPLE = {"small": 3e-5, "large": 3e-6}
#: Seconds a lane's measured slow-down (wall over CPU time) stays current.
CONTENTION_FRESH_S = 60.0
#: CPU seconds below which a job's wall/CPU ratio says nothing alone (a sleep, a refusal, a
#: short request): such jobs are summed until their CPU time reaches it.
CONTENTION_MIN_CPU_S = 0.05


class Contention:
    """How many times its CPU time a lane's job takes in wall time now: its slow-down.

    A running mean (weight :data:`COST_EWMA`) of wall over CPU seconds of the lane's
    finished jobs; None when none finished within :data:`CONTENTION_FRESH_S`. Per lane:
    the small lane's short Python-heavy jobs wait on each other for the interpreter lock
    and ran 5.3-5.7 times their CPU time at load 10-11 while a 2 M-sample upload,
    mostly in numpy and ONNX Runtime, took 15.7-18.4 s for its ~6 s of CPU.
    """

    def __init__(self) -> None:
        self.mean, self.at = 1.0, -math.inf
        self._pending = [0.0, 0.0, -math.inf]  # wall, CPU seconds of short jobs; since
        self._lock = threading.Lock()

    def measure(self, wall_s: float, cpu_s: float, now: float) -> None:
        """A finished job's wall and CPU seconds. Jobs shorter than
        :data:`CONTENTION_MIN_CPU_S` of CPU are summed until their CPU time reaches it (the
        small lane's requests of a few thousand samples take 0.03 s each on a quiet core:
        one alone says nothing, together they say the lane's slow-down)."""
        if not (math.isfinite(wall_s) and math.isfinite(cpu_s) and wall_s >= 0 and cpu_s >= 0):
            return
        with self._lock:
            if cpu_s < CONTENTION_MIN_CPU_S:
                pending = self._pending
                if now - pending[2] > CONTENTION_FRESH_S:  # old short jobs: start again
                    pending[:] = [0.0, 0.0, now]
                pending[0] += wall_s
                pending[1] += cpu_s
                if pending[1] < CONTENTION_MIN_CPU_S:
                    return
                wall_s, cpu_s = pending[0], pending[1]
                pending[:] = [0.0, 0.0, -math.inf]
            ratio = max(1.0, wall_s / cpu_s)
            fresh = now - self.at <= CONTENTION_FRESH_S
            self.mean = (1 - COST_EWMA) * self.mean + COST_EWMA * ratio if fresh else ratio
            self.at = now

    def factor(self, now: float) -> float | None:
        with self._lock:
            return self.mean if now - self.at <= CONTENTION_FRESH_S else None


def machine_slow_down(cores: int | None = None) -> float:
    """How many times its CPU time a CPU-bound thread started now takes, from the machine's
    load: ``(load + 1) / cores`` (the 1-minute load average of runnable threads, this one
    added, shared by the cores this process may use), at least 1.

    The stand-in for a lane with no slow-down of its own measured lately. At load 6.5 on 2
    cores it reads 3.75, and a 2 M-sample upload (~4-6 s of CPU) took 14.6-16.4 s there.
    The load average lags a change of load by about a minute; a started job is given its
    time up to the server's ceiling (``serving.app.OVERRUN_GRACE``).
    """
    try:
        load = os.getloadavg()[0]
        cores = cores or len(os.sched_getaffinity(0)) or 1
    except (OSError, AttributeError):  # pragma: no cover - no load average on this system
        return 1.0
    return max(1.0, (load + 1.0) / cores)


def thread_cpu_clock() -> tuple[int | None, float]:
    """The calling thread's CPU clock (readable from other threads) and its reading now:
    a running job's progress (:meth:`LaneCost.progress`)."""
    try:
        clock = time.pthread_getcpuclockid(threading.get_ident())
        return clock, time.clock_gettime(clock)
    except (AttributeError, OSError):  # pragma: no cover - not on Linux
        return None, 0.0


class LaneCost:
    """What one lane's predictions cost, and what it holds now: the basis of load shedding.

    The cost is seconds per sample. ``s_per_sample`` is a running mean (weight
    :data:`COST_EWMA`) of each finished prediction's wall time over its samples, ``seed``
    until the first one is measured; :meth:`s_per_sample_now` prices jobs at the highest of
    that mean, the latest measurement and what every running job has already spent per
    sample (a lower bound of its own cost) and the lane's CPU seconds per sample times
    its slow-down (:meth:`alone_s`), so that a rise of the machine's load counts
    at once and a fall only as the mean follows it. Wall time, not CPU time: on a shared
    machine the wall time is what the timeout counts. ``jobs`` holds every job submitted
    to the lane's ``workers`` and not yet ended (a job answered 504 included: it still
    holds its worker), as ticket -> ``[samples, start time or None]`` in submission order.
    Worker threads report starts and measurements, the event loop reads: one lock.
    """

    def __init__(self, workers: int, seed: float, cpu_seed: float = 0.0, live: bool = True) -> None:
        self.workers, self.s_per_sample, self.measured = workers, float(seed), 0
        self.live = live  # running jobs' progress counts in the slow-down (slow_down)
        self.latest = 0.0
        self.cpu_s_per_sample, self.cpu_measured = float(cpu_seed), 0
        self.contention = Contention()
        self.jobs: dict[int, list] = {}  # ticket -> [samples, start, CPU clock, its start]
        self._lock = threading.Lock()
        self._tickets = itertools.count()

    def _snapshot(self, now: float) -> tuple[float, list[tuple[float, float | None]]]:
        with self._lock:
            jobs = [(float(j[0]), j[1]) for j in self.jobs.values()]
            rate = max(self.s_per_sample, self.latest)
        spent = [(now - t) / n for n, t in jobs if t is not None and n > 0]
        return max([rate, *spent, self.alone_s(1, now) or 0.0]), jobs

    def alone_s(self, samples: int, now: float) -> float | None:
        """Seconds a job would take started now on a free worker: its CPU seconds (the lane's
        mean per sample) times the lane's slow-down now (:meth:`slow_down`); None when the
        lane has measured none lately."""
        factor = self.slow_down(now)
        return None if factor is None else samples * self.cpu_s_per_sample * factor

    def slow_down(self, now: float) -> float | None:
        """The lane's own slow-down now: the highest of its finished jobs' (:class:`Contention`,
        the last minute) and, if ``live``, its running jobs' so far (:meth:`progress`: what
        slows a job now slows it, whatever the cause); None when it has neither. ``live``
        is for a lane of long jobs (uploads: one may run tens of seconds with no job ending
        to measure the load); a lane of short jobs measures a finished one every fraction
        of a second, and a running one's reading, early in its life, is mostly noise."""
        with self._lock:
            running = [t for t in self.jobs if self.live and self.jobs[t][2] is not None]
        live = [self.progress(t, now) for t in running]
        ratios = [w / c for w, c in filter(None, live) if c >= CONTENTION_MIN_CPU_S]
        finished = self.contention.factor(now)
        found = ratios + ([finished] if finished is not None else [])
        return max(1.0, *found) if found else None

    def progress(self, ticket: int, now: float) -> tuple[float, float] | None:
        """A running job's wall and CPU seconds so far (its thread's CPU clock); None if it is
        not running or its clock cannot be read."""
        with self._lock:
            job = self.jobs.get(ticket)
            if job is None or job[1] is None or job[2] is None:
                return None
            start, clock, cpu0 = job[1], job[2], job[3]
            try:
                cpu = time.clock_gettime(clock) - cpu0
            except OSError:  # its thread is gone
                return None
        return now - start, max(cpu, 0.0)

    def s_per_sample_now(self, now: float) -> float:
        """Seconds per sample a job is priced at, at time `now` (see the class notes)."""
        return self._snapshot(now)[0]

    def expected_s(self, samples: int, now: float) -> float:
        """Seconds a prediction of `samples` samples is expected to take once started."""
        return samples * self.s_per_sample_now(now)

    def expected_start_s(self, now: float) -> float:
        """Seconds until a worker would take a job submitted at `now`.

        List scheduling of the estimates: each running job frees its worker when its
        estimate is spent (at least :data:`OVERRUN_LEFT` of it ahead, while it runs),
        the queued ones take the first free worker in their order, as the pool does.
        """
        rate, jobs = self._snapshot(now)
        free = [max(n * rate - (now - t), OVERRUN_LEFT * n * rate)
                for n, t in jobs if t is not None]  # fmt: skip
        free += [0.0] * max(0, self.workers - len(free))
        heapq.heapify(free)
        for n, t in jobs:
            if t is None:
                heapq.heappush(free, heapq.heappop(free) + n * rate)
        return free[0]

    def submitted(self, samples: int) -> int:
        """Record a job of `samples` samples handed to the pool; its ticket."""
        ticket = next(self._tickets)
        with self._lock:
            self.jobs[ticket] = [samples, None, None, 0.0]
        return ticket

    def started(self, ticket: int, now: float, clock: int | None = None, cpu0: float = 0.0) -> None:
        """The job's worker started it at `now`; `clock` is that thread's CPU clock, which
        read `cpu0` then (:func:`thread_cpu_clock`), so that its progress can be read."""
        with self._lock:
            if ticket in self.jobs:
                self.jobs[ticket][1:] = [now, clock, cpu0]

    def ended(self, ticket: int) -> None:
        """The job left its worker (finished, failed or cancelled before it ran)."""
        with self._lock:
            self.jobs.pop(ticket, None)

    def measure(self, samples: int, seconds: float, cpu_s: float | None = None) -> None:
        """A prediction of `samples` samples took `seconds` of wall time (and `cpu_s` of its
        thread's CPU time): update the means and the lane's slow-down."""
        if samples <= 0 or not math.isfinite(seconds) or seconds < 0:
            return
        rate = seconds / samples
        with self._lock:
            mean = (1 - COST_EWMA) * self.s_per_sample + COST_EWMA * rate
            self.s_per_sample = mean if self.measured else rate
            self.latest = rate
            self.measured += 1
            if cpu_s is not None and cpu_s >= CONTENTION_MIN_CPU_S:
                cpu = cpu_s / samples
                mean = (1 - COST_EWMA) * self.cpu_s_per_sample + COST_EWMA * cpu
                self.cpu_s_per_sample = mean if self.cpu_measured else cpu
                self.cpu_measured += 1
        if cpu_s is not None:
            self.contention.measure(seconds, cpu_s, time.monotonic())
