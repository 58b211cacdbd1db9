"""Throughput of the ONNX predictor on one core: a 60 s recording sampled at 2 kHz.

Simulates the recording (beta 30, the paper's rig, f_n = 9.48 Hz), pins the
process to one CPU, and times, in process:

* ``full``: :meth:`serving.predictor.Predictor.predict` - checks, the model over
  the log's sliding windows (hop 0.5 s, 117 windows of 16 natural periods; the
  recording's estimate, its segments and its layers all read these outputs), the
  geometric and restoring-force cross-checks, the alarm (what ``stiffnet predict``
  and ``POST /predict`` run after reading the file);
* ``per-row polarity, embedding twice (before)``: the same prediction with the CNN's
  polarity rule row by row (``windows._polarities_per_row``: a find_peaks and an
  impact_polarity per window) and the alarm computing the windows' embedding distances
  again - the baseline of this speed-up, measured in the same run (the predictions are
  checked equal);
* ``two passes (session 5)``: the same plus the work the one pass removed - the model
  over the recording's own non-overlapping windows (35) with their geometric
  features, and the geometric features the log computed beyond its model's input
  along its pass (the CNN's 3);
* its steps: the model over the sliding windows (family input + ONNX Runtime),
  the CNN's canonical windows (input before the delay channels) and their polarity rule
  batched and row by row, the geometric cross-check's features, the restoring-force
  cross-check (and, for information, the same with its high-pass profile patched out),
  the layers from the shared outputs, the alarm's embedding distances.

Prints the median wall and CPU (process) times - on a busy machine the CPU time
is the better guide to the quiet-machine wall time - the load average before and
after, the speed-ups as CPU-time ratios, and ends with ``realtime_factor: X`` =
recording seconds / median wall time of the full prediction (target >= 1000) and the
CPU-time factor. Run::

    python benchmarks/bench_predictor.py [--quick] [--model models/gbm.onnx]
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")  # one core, before numpy loads

import argparse  # noqa: E402
import json  # noqa: E402
import statistics  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402
from unittest import mock  # noqa: E402

import numpy as np  # noqa: E402

DURATION_S, FS_HZ, FN_HZ = 60.0, 2000.0, 9.48


def simulate() -> np.ndarray:
    """The benchmark recording (deterministic)."""
    from stiffnet.campaign import simulate_campaign
    from stiffnet.recordings import read_recording

    with tempfile.TemporaryDirectory() as tmp:
        manifest = Path(tmp) / "manifest.csv"
        manifest.write_text(
            "recording,fs_hz,natural_frequency_hz,frequency_ratio,amplitude,gap,damping_ratio,"
            f"beta,duration_s,noise\nr.csv,{FS_HZ},{FN_HZ},1.05,1.9,2.8,0.02,30,{DURATION_S},0.02\n"
        )
        out = simulate_campaign(manifest, Path(tmp) / "c", [], seed=0)
        return read_recording(Path(out) / "r.csv").accel


def timed(fn, repeats: int) -> tuple[float, float]:
    """Median wall and CPU (process) seconds of `fn` over `repeats` calls after a warm-up."""
    fn()
    wall, cpu = [], []
    for _ in range(repeats):
        t, c = time.perf_counter(), time.process_time()
        fn()
        wall.append(time.perf_counter() - t)
        cpu.append(time.process_time() - c)
    return statistics.median(wall), statistics.median(cpu)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer repeats")
    ap.add_argument("--model", default=None, help="ONNX model (default models/cnn.onnx)")
    args = ap.parse_args()
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})
    from serving import predictor
    from serving.log import MAX_HOP_S, hop_samples, record_layers, window_embedding_scores
    from serving.predictor import Predictor
    from serving.restoring_force_check import restoring_force_check
    from stiffnet.features import features_and_estimate, windows
    from stiffnet.features.windows import window_length, window_starts
    from stiffnet.restoring_force import estimate as rf_estimate
    from stiffnet.uncertainty.alarm_verdict import alarm_verdict

    load_before = os.getloadavg()
    a = simulate()
    p = Predictor.load(args.model, threads=1)
    repeats = 5 if args.quick else 30
    n = window_length(FS_HZ, FN_HZ, p.window_periods)
    sliding = window_starts(a.size, n, hop_samples(MAX_HOP_S, FS_HZ))
    own = window_starts(a.size, n, n)  # the recording's non-overlapping windows
    family = p.model.family
    geo_idx = family.feature_windows(len(sliding), p.geometric_windows)

    def full():
        return p.predict(a, FS_HZ, natural_frequency_hz=FN_HZ)

    def features(starts, idx):
        for i in idx:
            features_and_estimate(a[starts[i] : starts[i] + n], FS_HZ, FN_HZ,
                                  calibration=p.calibration)  # fmt: skip

    # the geometric features the log's pass computed beyond its model's input (CNN: 3;
    # GBM: none, its input is every window's features)
    log_extra = np.setdiff1d(geo_idx, family.feature_windows(len(sliding), 0))

    def two_passes():
        full()
        p._run_model(a, own, n, FS_HZ, FN_HZ)  # the recording's own windows, again
        features(sliding, log_extra)

    def before():
        """The prediction as it was: polarity row by row, the embedding distances twice."""
        with (
            mock.patch.object(windows, "canonical_polarities", windows._polarities_per_row),
            mock.patch.object(predictor, "alarm_verdict", lambda *x: alarm_verdict(*x[:5])),
        ):
            return full()

    def without_profile(fn):
        """What the check costs without its high-pass profile (information, not a result:
        on this record the profile keeps no corner, docs/serving.md)."""
        with mock.patch.object(rf_estimate, "_profiled_corner", lambda m, c, *_: (m, c)):
            return fn()

    out, _, _ = p._run_model(a, sliding, n, FS_HZ, FN_HZ, geometric_windows=0)
    emb = window_embedding_scores(p.alarm, out)
    ok = np.ones(len(sliding), dtype=bool)
    cut = a[sliding[:, None] + np.arange(n)]
    std = (cut - cut.mean(axis=1, keepdims=True)) / cut.std(axis=1, keepdims=True)
    period = FS_HZ / FN_HZ
    same = json.dumps(before(), sort_keys=True) == json.dumps(full(), sort_keys=True)
    same_pol = np.array_equal(windows.canonical_polarities(std, period),
                              windows._polarities_per_row(std, period))  # fmt: skip
    rows = [
        ("full (one pass over the log's windows)", timed(full, repeats)),
        ("per-row polarity, embedding twice (before)", timed(before, repeats)),
        ("two passes (session 5)", timed(two_passes, repeats)),
        (
            f"model: {family.kind} input + ONNX ({len(sliding)} windows)",
            timed(lambda: p._run_model(a, sliding, n, FS_HZ, FN_HZ, geometric_windows=0),
                  repeats),
        ),  # fmt: skip
        ("  canonical windows (batched polarity)",
         timed(lambda: windows.canonical_windows(cut, FS_HZ, FN_HZ), repeats)),
        ("  polarity rule, batched",
         timed(lambda: windows.canonical_polarities(std, period), repeats)),
        ("  polarity rule, row by row (before)",
         timed(lambda: windows._polarities_per_row(std, period), repeats)),
        (f"geometric features ({len(geo_idx)} windows)",
         timed(lambda: features(sliding, geo_idx), repeats)),
        ("restoring-force cross-check",
         timed(lambda: restoring_force_check(a, FS_HZ, FN_HZ), repeats)),
        ("  the same, its high-pass profile patched out",
         timed(lambda: without_profile(lambda: restoring_force_check(a, FS_HZ, FN_HZ)),
               repeats)),
        ("layers from the shared outputs",
         timed(lambda: record_layers(p, a, FS_HZ, FN_HZ, windows=(ok, out, emb)), repeats)),
        ("alarm: embedding distances (once now)",
         timed(lambda: window_embedding_scores(p.alarm, out), repeats)),
    ]  # fmt: skip
    r = full()
    load_after = os.getloadavg()
    print(
        f"recording: {DURATION_S:g} s at {FS_HZ:g} Hz ({a.size} samples, {r['n_windows']} "
        f"windows, hop {r['hop_s']:g} s); model {p.name} ({p.kind}); class {r['class']}, "
        f"beta {r['beta']:.3g}; geometric {r['geometric']['class']}; median of {repeats}"
    )
    print(f"load average (1, 5, 15 min): before {load_before}, after {load_after}")
    print(f"before and now predict the same: {same}; polarities equal: {same_pol}")
    print(f"{'step':<44} {'wall ms':>9} {'realtime x':>11} {'cpu ms':>9} {'cpu x':>7}")
    for name, (sec, cpu) in rows:
        print(f"{name:<44} {1e3 * sec:9.2f} {DURATION_S / sec:11.0f} {1e3 * cpu:9.2f}"
              f" {DURATION_S / cpu:7.0f}")  # fmt: skip
    (w1, c1), (w0, c0), (w2, c2) = rows[0][1], rows[1][1], rows[2][1]
    print(f"speed-up over before: cpu {c0 / c1:.2f}x (wall {w0 / w1:.2f}x)")
    print(f"speed-up over two passes: cpu {c2 / c1:.2f}x (wall {w2 / w1:.2f}x)")
    print(f"realtime_factor: {DURATION_S / w1:.0f} (cpu: {DURATION_S / c1:.0f}; target >= 1000)")


if __name__ == "__main__":
    main()
