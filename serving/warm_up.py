"""Warm-up at server start: one small prediction through each lane's code path, bounded.

``stiffnet serve`` runs :func:`warm_up` after the model is loaded and before the port is
served. Each lane's worker runs what a request of that lane runs: a JSON body
(``POST /predict`` and ``POST /log``: the pydantic parser, the ONNX session, the CNN's
input or the GBM's features, the geometric and restoring-force cross-checks, the alarm,
the stiffness log) on the small lane's pool, an ``.npy`` upload spooled to a file (the
recording reader and its format registry) on the large lane's thread. So the first
client does not pay for lazy imports, ONNX Runtime's first allocations and the readers'
discovery, the small lane starts with its cost per sample measured (the basis of load
shedding, :mod:`serving.load_shedding`) rather than assumed, and a model or environment
that cannot predict is found before anyone is served: :class:`WarmUpFailed`, one line.
"""

from __future__ import annotations

import io
import json
import math
import time
from concurrent.futures import Future
from concurrent.futures import TimeoutError as FutureTimeout
from typing import TYPE_CHECKING, Any

import numpy as np

from stiffnet.errors import EnvironmentFailure
from stiffnet.inputs import one_line

if TYPE_CHECKING:
    from serving.app import Admission

#: The warm-up recording: 6 s at 2 kHz of an oscillator with f_n = 10 Hz, forced at
#: 0.8 f_n onto a stiff face (beta 40, within the shipped model's range), after 3 s of
#: start-up transient: the size and kind of a small request (the load benchmark's is 5 s
#: of the example at 1 kHz), steady enough for the restoring-force check to read its
#: contact (13 samples per impact: its beta reads 39.3; the shipped CNN answers 50.0).
WARM_UP_FS_HZ = 2000.0
WARM_UP_FN_HZ = 10.0
WARM_UP_SECONDS = 6.0
WARM_UP_TRANSIENT_S = 3.0
#: The stiffness ratio, damping ratio, gap and forcing (paper eqs 11-12, units of the
#: free oscillator: displacement over the static one, time over 1/omega_n).
WARM_UP_BETA, WARM_UP_ZETA, WARM_UP_GAP, WARM_UP_FORCE, WARM_UP_RATIO = 40.0, 0.1, 0.3, 1.0, 0.8
#: Integration sub-steps per sample (semi-implicit Euler: stable for omega h << 1 with
#: the contact's sqrt(1 + beta) = 6.4 times the free frequency: 0.025 rad a step).
SUBSTEPS = 8
#: Warm-up seconds allowed at most, in units of ``--timeout-s``: its three predictions took
#: 16.3 s in all at load 17 (2 cores; 2.8 s at load 7), and a server that cannot make them
#: in twice the time it gives one request would refuse or time out every request.
WARM_UP_SHARE = 2.0


class WarmUpFailed(EnvironmentFailure):
    """The server could not predict at start (the model, its runtime or the machine): exit 1."""


def warm_up_recording(
    fs_hz: float = WARM_UP_FS_HZ,
    natural_frequency_hz: float = WARM_UP_FN_HZ,
    seconds: float = WARM_UP_SECONDS,
) -> np.ndarray:
    """Acceleration of a forced impact oscillator (paper eqs 11-12) with a linear contact.

    ``x'' + 2 zeta x' + x + beta (x - e) H(x - e) = F cos(r t)`` in the free oscillator's
    units, integrated by semi-implicit Euler at :data:`SUBSTEPS` steps per sample from
    rest, the first :data:`WARM_UP_TRANSIENT_S` seconds dropped; the acceleration is
    sampled at ``fs_hz`` with time scaled by ``2 pi natural_frequency_hz``.
    Deterministic and numpy-only: no simulator, no file.
    """
    skip = int(round(WARM_UP_TRANSIENT_S * fs_hz))
    n = skip + int(round(seconds * fs_hz))
    h = 2.0 * math.pi * natural_frequency_hz / fs_hz / SUBSTEPS
    accel = np.empty(n)
    x = v = t = 0.0
    beta, zeta, gap, force, ratio = (WARM_UP_BETA, WARM_UP_ZETA, WARM_UP_GAP, WARM_UP_FORCE,
                                     WARM_UP_RATIO)  # fmt: skip
    for i in range(n):
        for _ in range(SUBSTEPS):
            a = force * math.cos(ratio * t) - 2.0 * zeta * v - x - beta * max(x - gap, 0.0)
            v += h * a
            x += h * v
            t += h
        accel[i] = force * math.cos(ratio * t) - 2.0 * zeta * v - x - beta * max(x - gap, 0.0)
    return accel[skip:]


def warm_up(admission: Admission, timeout_s: float | None = None) -> str:
    """Run the warm-up predictions on `admission`'s lanes; one line saying what it did.

    The small lane predicts and logs the JSON body of :func:`warm_up_recording` (its
    prediction measured into the lane's cost, as a served one is); the large lane
    predicts it as an uploaded ``.npy``, measured into the lane's slow-down (wall over
    CPU time, :class:`~serving.load_shedding.Contention`) only: a 6 s recording's cost per
    sample says little of a 2 M-sample upload's (fixed costs dominate it). All within
    ``timeout_s`` (``--timeout-s`` times :data:`WARM_UP_SHARE`).

    Raises
    ------
    WarmUpFailed
        A warm-up prediction failed or did not finish in time (one line naming it).
    """
    from serving.app import _predict_file, _predict_json, spool_upload

    limits = admission.limits
    budget = WARM_UP_SHARE * limits.timeout_s if timeout_s is None else float(timeout_s)
    t_start = time.monotonic()
    deadline = t_start + budget
    accel = warm_up_recording()
    body = json.dumps({"samples": accel.tolist(), "fs_hz": WARM_UP_FS_HZ,
                       "natural_frequency_hz": WARM_UP_FN_HZ}).encode()  # fmt: skip
    buf = io.BytesIO()
    np.save(buf, accel)
    buf.seek(0)
    predictor, n = admission.predictor, accel.size
    timings: list[str] = []

    def timed(job: Any) -> tuple[Any, float, float]:
        t0, cpu0 = time.monotonic(), time.thread_time()
        result = job()
        return result, time.monotonic() - t0, time.thread_time() - cpu0

    steps = (
        ("predict", admission.small, lambda: _predict_json(predictor, body, limits.max_samples)),
        ("log", admission.small,
         lambda: _predict_json(predictor, body, limits.max_samples, "log")),
        ("large lane .npy", admission.large,
         lambda: _predict_file(predictor, spool_upload(buf, "warm-up.npy"), "warm-up.npy",
                               str(WARM_UP_FS_HZ), str(WARM_UP_FN_HZ), limits.max_samples)),
    )  # fmt: skip
    for name, pool, job in steps:
        fut: Future = pool.submit(timed, job)
        try:
            result, wall, cpu = fut.result(timeout=max(0.0, deadline - time.monotonic()))
        except FutureTimeout:
            raise WarmUpFailed(
                f"warm-up: the {name} of a {WARM_UP_SECONDS:g} s recording did not finish "
                f"within {budget:g} s ({WARM_UP_SHARE:g} x --timeout-s): this server could not "
                "answer in time"
            ) from None
        except Exception as exc:  # any failure: the server must not start
            raise WarmUpFailed(
                f"warm-up: the {name} of a {WARM_UP_SECONDS:g} s recording failed: "
                f"{type(exc).__name__}: {one_line(exc, 300)}"
            ) from None
        _check_result(name, result)
        if name == "predict":
            admission.cost["small"].measure(n, wall, cpu)
        elif name == "large lane .npy":  # its slow-down (a ratio) holds for any size
            admission.cost["large"].contention.measure(wall, cpu, time.monotonic())
        timings.append(f"{name} {wall:.2f} s")
    total = time.monotonic() - t_start
    return (
        f"warm-up: {len(steps)} predictions of a {WARM_UP_SECONDS:g} s recording ({n} samples) "
        f"in {total:.2f} s ({', '.join(timings)}); small lane cost "
        f"{admission.cost['small'].s_per_sample * 1e6:.3g} us per sample"
    )


def _check_result(name: str, result: Any) -> None:
    """A warm-up answer is a document the routes would send: a dict, finite numbers."""
    if not isinstance(result, dict):
        raise WarmUpFailed(f"warm-up: the {name} returned {type(result).__name__}, not a document")
    beta = result.get("beta")
    if name != "log" and not (isinstance(beta, float) and math.isfinite(beta)):
        raise WarmUpFailed(f"warm-up: the {name} gave no finite beta ({beta!r})")
