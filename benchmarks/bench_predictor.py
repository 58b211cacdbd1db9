"""Throughput of the ONNX predictor on one core: a 60 s recording sampled at 2 kHz.

Simulates the recording (beta 30, the paper's rig, f_n = 9.48 Hz; 35 windows of 16
natural periods), pins the process to one CPU, and times, in process:

* ``full``: :meth:`serving.predictor.Predictor.predict` - checks, windows, the
  model, the geometric cross-check and the OOD score (what ``stiffnet predict``
  and ``POST /predict`` run after reading the file);
* ``onnx path``: the model family's input (CNN: canonical windows; GBM: the
  features already computed) + the ONNX Runtime call only;
* ``cross-check + OOD``: the geometric method and OOD features on the windows
  the family picks (the GBM's model input: all of them).

Prints the median wall and CPU (process) times - on a busy machine the CPU time
is the better guide to the quiet-machine wall time - and ends with
``realtime_factor: X`` = recording seconds / median wall time of the full
prediction (target >= 1000). Run on a quiet machine::

    python benchmarks/bench_predictor.py [--quick] [--model models/gbm.onnx]
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")  # one core, before numpy loads

import argparse  # noqa: E402
import statistics  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

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
    from serving.predictor import Predictor
    from stiffnet.features import features_and_estimate
    from stiffnet.features.windows import window_length, window_starts

    a = simulate()
    p = Predictor.load(args.model, threads=1)
    repeats = 5 if args.quick else 30
    n = window_length(FS_HZ, FN_HZ, p.window_periods)
    starts = window_starts(a.size, n, n)
    W = a[starts[:, None] + np.arange(n)[None, :]]

    full = timed(lambda: p.predict(a, FS_HZ, natural_frequency_hz=FN_HZ), repeats)
    rows = [("full (model + cross-check + OOD)", full)]
    # the model family's own steps (serving.families): its input, then ONNX Runtime
    family = p.model.family
    idx = family.feature_windows(len(W), p.geometric_windows)

    def cross_check():
        feats = [features_and_estimate(W[i], FS_HZ, FN_HZ, calibration=p.calibration) for i in idx]
        X = np.array([f for f, _ in feats]).reshape(len(feats), -1)
        if p.ood is not None:
            p.ood.scores(X)
        return X

    feats = cross_check()
    X = family.model_input(W, FS_HZ, FN_HZ, feats)

    def onnx_run():
        return p.model.session.run(["probabilities", "log_beta"], {p.model.input_name: X})

    t_in = timed(lambda: family.model_input(W, FS_HZ, FN_HZ, feats), repeats)
    t_onnx = timed(onnx_run, repeats)
    rows += [
        (f"onnx path: {family.kind} input", t_in),
        ("onnx path: ONNX Runtime", t_onnx),
        ("onnx path total", (t_in[0] + t_onnx[0], t_in[1] + t_onnx[1])),
        (f"cross-check + OOD ({len(idx)} windows)", timed(cross_check, repeats)),
    ]
    r = p.predict(a, FS_HZ, natural_frequency_hz=FN_HZ)
    print(
        f"recording: {DURATION_S:g} s at {FS_HZ:g} Hz ({a.size} samples, {r['n_windows']} "
        f"windows); model {p.name} ({p.kind}); class {r['class']}, beta {r['beta']:.3g}; "
        f"geometric {r['geometric']['class']}; median of {repeats}"
    )
    print(f"{'step':<40} {'wall ms':>9} {'realtime x':>11} {'cpu ms':>9}")
    for name, (sec, cpu) in rows:
        print(f"{name:<40} {1e3 * sec:9.2f} {DURATION_S / sec:11.0f} {1e3 * cpu:9.2f}")
    print(f"realtime_factor: {DURATION_S / full[0]:.0f}")


if __name__ == "__main__":
    main()
