"""ONNX Runtime latency of the shipped models and their per-window preparation cost.

For ``models/cnn.onnx`` and ``models/gbm.onnx``, in ONNX Runtime on the CPU
with ``intra_op_num_threads=1`` (and one inter-op thread):

* **batch 1**: median wall-clock time of one ``session.run`` on one window
  over ``--repeats`` calls (after warm-up), each call on the next window;
* **batch 256**: median time of one run on 256 windows, divided by 256.

Reported as ms per window and windows/s. Separately, the **preparation cost**
of one window from raw acceleration, median over ``--n-prep`` windows:
the CNN's canonical delay-embedded window
(:func:`stiffnet.features.windows.window_tensor`, resampling included) and the
GBM's 23 inclination features (:func:`stiffnet.features.inclination_features`,
which runs the geometric chain). Windows come from the dataset given by
``--data`` (``data/default`` by default; their sampling rates vary, 50 to 500
samples per natural period, 16 periods).

Run (under a minute): ``OMP_NUM_THREADS=1 python benchmarks/bench_onnx_latency.py
[--quick] [--out FILE.json]``. On a shared machine the numbers are contended;
the load average is recorded with them.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from stiffnet.dataset.store import load_dataset
from stiffnet.features import inclination_features
from stiffnet.features.windows import window_tensor
from stiffnet.io_utils import write_json_atomic

ROOT = Path(__file__).resolve().parents[1]


def _session(path: Path) -> Any:
    import onnxruntime as ort

    so = ort.SessionOptions()
    so.intra_op_num_threads = 1
    so.inter_op_num_threads = 1
    return ort.InferenceSession(str(path), so, providers=["CPUExecutionProvider"])


def _meta(sess: Any) -> dict[str, Any]:
    from serving.model import onnx_metadata

    return onnx_metadata(sess)


def _run_latency(sess: Any, x: np.ndarray, repeats1: int, repeats256: int) -> dict[str, float]:
    """Median per-window latency at batch 1 and batch 256."""
    name = sess.get_inputs()[0].name
    x = np.ascontiguousarray(x, np.float32)
    for i in range(10):  # warm-up
        sess.run(None, {name: x[i % len(x)][None]})
    t1 = []
    for i in range(repeats1):
        xi = x[i % len(x)][None]
        t = time.perf_counter()
        sess.run(None, {name: xi})
        t1.append(time.perf_counter() - t)
    big = np.ascontiguousarray(np.resize(x, (256, *x.shape[1:])), np.float32)
    sess.run(None, {name: big})
    t256 = []
    for _ in range(repeats256):
        t = time.perf_counter()
        sess.run(None, {name: big})
        t256.append(time.perf_counter() - t)
    m1, m256 = float(np.median(t1)), float(np.median(t256)) / 256
    return {
        "batch1_ms": round(1e3 * m1, 4),
        "batch1_windows_per_s": round(1.0 / m1, 1),
        "batch256_ms_per_window": round(1e3 * m256, 4),
        "batch256_windows_per_s": round(1.0 / m256, 1),
        "repeats_batch1": repeats1,
        "repeats_batch256": repeats256,
    }


def measure(
    cnn_path: Path,
    gbm_path: Path,
    data_dir: Path,
    quick: bool = False,
    n_prep: int | None = None,
    repeats: int | None = None,
) -> dict[str, Any]:
    """Latency of both ONNX models and the preparation cost per window.

    Parameters
    ----------
    cnn_path, gbm_path : Path
        The ONNX files.
    data_dir : Path
        A dataset folder providing raw windows.
    quick : bool, optional
        Fewer windows and repeats (smoke run).
    n_prep : int, optional
        Windows timed for the preparation cost (default 200, 20 if quick).
    repeats : int, optional
        Batch-1 repeats (default 300, 30 if quick); batch 256 gets a tenth, at least 5.

    Returns
    -------
    dict
        ``cnn`` and ``gbm``: latency; ``prep``: ms per window of each input;
        ``load_average``.
    """
    n_prep = n_prep or (20 if quick else 200)
    repeats = repeats or (30 if quick else 300)
    ds = load_dataset(data_dir)
    rng = np.random.default_rng(0)
    idx = rng.choice(len(ds), size=min(len(ds), max(n_prep, 256)), replace=False)
    wins = ds.windows()
    fs = ds.column("fs_hz")
    fn = ds.column("natural_frequency_hz")

    cnn = _session(cnn_path)
    meta = _meta(cnn)
    rate, periods = int(meta["canonical_rate"]), int(meta["window_periods"])
    delays = [int(d) for d in meta["delays"]]
    t_cnn, t_gbm, xs, fs_list = [], [], [], []
    for i in idx[:n_prep]:
        t = time.perf_counter()
        window_tensor([wins[i]], fs[i], fn[i], rate, periods, delays)
        t_cnn.append(time.perf_counter() - t)
        t = time.perf_counter()
        inclination_features(wins[i], float(fs[i]), float(fn[i]))
        t_gbm.append(time.perf_counter() - t)
    xs = window_tensor([wins[i] for i in idx], fs[idx], fn[idx], rate, periods, delays)
    feats = np.stack([inclination_features(wins[i], float(fs[i]), float(fn[i]))
                      for i in idx[: min(len(idx), 64)]])  # fmt: skip
    fs_list = fs[idx[:n_prep]] / fn[idx[:n_prep]]
    gbm = _session(gbm_path)
    r256 = max(5, repeats // 10)
    return {
        "cnn": _run_latency(cnn, xs, repeats, r256),
        "gbm": _run_latency(gbm, feats, repeats, r256),
        "prep": {
            "cnn_window_ms": round(1e3 * float(np.median(t_cnn)), 3),
            "gbm_features_ms": round(1e3 * float(np.median(t_gbm)), 3),
            "n_windows": int(n_prep),
            "samples_per_natural_period_median": round(float(np.median(fs_list)), 1),
            "raw_window_samples_median": int(np.median([wins[i].size for i in idx[:n_prep]])),
        },
        "onnxruntime_threads": {"intra_op": 1, "inter_op": 1},
        "load_average": list(os.getloadavg()),
        "omp_num_threads": os.environ.get("OMP_NUM_THREADS"),
    }


def markdown(lat: dict[str, Any]) -> str:
    """Latency and preparation cost as a markdown table."""
    p = lat["prep"]
    rows = [
        "| model | prepare one window (ms) | batch 1 (ms) | batch 1 (windows/s) "
        "| batch 256 (ms/window) | batch 256 (windows/s) |",
        "| --- | --- | --- | --- | --- | --- |",
    ]
    for name, prep in (("CNN", p["cnn_window_ms"]), ("GBM", p["gbm_features_ms"])):
        r = lat[name.lower()]
        rows.append(
            f"| {name} | {prep:.2f} | {r['batch1_ms']:.3f} | {r['batch1_windows_per_s']:,.0f} "
            f"| {r['batch256_ms_per_window']:.4f} | {r['batch256_windows_per_s']:,.0f} |"
        )
    la = ", ".join(f"{v:.2f}" for v in lat["load_average"])
    rows.append("")
    rows.append(f"(ONNX Runtime intra_op_num_threads=1; load average {la})")
    return "\n".join(rows)


def main(argv: list[str] | None = None) -> int:
    """Command-line entry point."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--models", type=Path, default=ROOT / "models")
    ap.add_argument("--data", type=Path, default=ROOT / "data" / "default")
    ap.add_argument("--repeats", type=int, default=None, help="batch-1 repeats (default 300)")
    ap.add_argument("--n-prep", type=int, default=None, help="windows timed for preparation")
    ap.add_argument("--out", type=Path, default=None, help="JSON result (written atomically)")
    ap.add_argument("--quick", action="store_true", help="small smoke run")
    args = ap.parse_args(argv)
    t = time.perf_counter()
    lat = measure(args.models / "cnn.onnx", args.models / "gbm.onnx", args.data, args.quick,
                  args.n_prep, args.repeats)  # fmt: skip
    print(markdown(lat))
    if args.out:
        write_json_atomic(args.out, lat)
    print(f"({time.perf_counter() - t:.1f} s)", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
