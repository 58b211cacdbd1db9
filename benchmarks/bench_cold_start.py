"""Cold start of ``stiffnet predict`` on one file: wall and CPU time, and where imports go.

Each run is a fresh ``python -m stiffnet predict examples/recordings/impact_beta45.csv``
process. Measured in the same run, so that a busy machine affects every row alike:

* ``python -c pass``: the interpreter alone (site, the editable-install finder);
* ``deps without scipy.signal``: ``import numpy, onnxruntime, pyarrow.csv, typer,
  rich.table, pydantic`` - the predictor's unavoidable dependencies;
* ``import scipy.signal``: the one dependency the predictor's DSP needs
  (Butterworth + ``sosfiltfilt``, Savitzky-Golay, ``find_peaks``); it imports
  scipy.stats, interpolate, optimize, spatial and sparse with it;
* ``predict (this tree)``, and ``predict (baseline)`` with ``--baseline-src DIR``
  (an older checkout, e.g. ``git worktree add /tmp/base <commit>``): the command.

The CPU time (user + sys of the child) is the better guide on a shared machine.
Then one ``python -X importtime`` run lists the largest imports (cumulative ms) and
the modules that must never load on this path (pandas, torch, scikit-learn,
mlflow, matplotlib, dask).

    python benchmarks/bench_cold_start.py [--repeats 7] [--baseline-src /tmp/base]
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "recordings" / "impact_beta45.csv"
PREDICT = ["-m", "stiffnet", "predict", str(EXAMPLE)]
DEPS = "import numpy, onnxruntime, pyarrow.csv, typer, rich.table, pydantic"
NEVER = ("pandas", "torch", "sklearn", "mlflow", "matplotlib", "dask")
TARGET_S = 1.0


def _env(src: Path) -> dict[str, str]:
    env = dict(os.environ, OMP_NUM_THREADS="1", PYTHONPATH=str(src), COLUMNS="100")
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    return env


def run_once(args: list[str], src: Path) -> tuple[float, float]:
    """Wall and CPU (user + sys) seconds of one fresh interpreter."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, *args], cwd=ROOT, env=_env(src),
                          capture_output=True, text=True)  # fmt: skip
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(args)} failed:\n{proc.stderr[-2000:]}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu


def measure(args: list[str], src: Path, repeats: int) -> dict[str, float]:
    run_once(args, src)  # warm the file cache and the .pyc files
    walls, cpus = zip(*(run_once(args, src) for _ in range(repeats)), strict=True)
    return {
        "wall_min": min(walls),
        "wall_median": statistics.median(walls),
        "cpu_min": min(cpus),
        "cpu_median": statistics.median(cpus),
    }


def import_profile(src: Path) -> tuple[list[tuple[str, float]], list[str]]:
    """Largest top-level imports (cumulative ms) of one ``-X importtime`` predict run."""
    proc = subprocess.run([sys.executable, "-X", "importtime", *PREDICT], cwd=ROOT,
                          env=_env(src), capture_output=True, text=True)  # fmt: skip
    cumulative: dict[str, float] = {}
    names: set[str] = set()
    for line in proc.stderr.splitlines():
        if not line.startswith("import time:") or "|" not in line:
            continue
        _self, cum, name = line.removeprefix("import time:").split("|")
        if not cum.strip().isdigit():
            continue
        depth = (len(name) - len(name.lstrip())) // 2
        key = name.strip()
        names.add(key)
        if depth <= 2 and "." not in key or key in ("scipy.signal", "serving.predictor"):
            cumulative[key] = max(cumulative.get(key, 0.0), int(cum) / 1000)
    loaded = [m for m in NEVER if m in names]
    top = sorted(cumulative.items(), key=lambda kv: -kv[1])[:12]
    return top, loaded


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--baseline-src", type=Path, help="an older checkout to compare with")
    args = ap.parse_args()

    rows = [
        ("python -c pass", ["-c", "pass"], ROOT),
        ("deps without scipy.signal", ["-c", DEPS], ROOT),
        ("import scipy.signal", ["-c", "import scipy.signal"], ROOT),
        ("predict (this tree)", PREDICT, ROOT),
    ]
    if args.baseline_src is not None:
        rows.append(("predict (baseline)", PREDICT, args.baseline_src.resolve()))
    results = {name: measure(cmd, src, args.repeats) for name, cmd, src in rows}
    bare = results["python -c pass"]["cpu_median"]
    print(f"cold start, {args.repeats} fresh processes per row (after one warm-up)\n")
    print("| command | wall min s | wall median s | CPU min s | CPU median s | CPU / bare |")
    print("| --- | ---: | ---: | ---: | ---: | ---: |")
    for name, r in results.items():
        print(f"| {name} | {r['wall_min']:.3f} | {r['wall_median']:.3f} | {r['cpu_min']:.3f} "
              f"| {r['cpu_median']:.3f} | {r['cpu_median'] / bare:.1f}x |")  # fmt: skip
    ours = results["predict (this tree)"]
    if "predict (baseline)" in results:
        base = results["predict (baseline)"]
        print(f"\nCPU ratio this tree / baseline: {ours['cpu_median'] / base['cpu_median']:.2f}")
    top, loaded = import_profile(ROOT)
    print("\n| import (cumulative, one -X importtime run) | ms |\n| --- | ---: |")
    for name, ms in top:
        print(f"| {name} | {ms:.0f} |")
    print(f"\nnever-loaded modules that loaded: {', '.join(loaded) or 'none'}")
    verdict = "meets" if ours["cpu_median"] <= TARGET_S else "misses"
    print(
        f"predict cold start {ours['cpu_median']:.2f} s CPU (median) {verdict} the "
        f"{TARGET_S:g} s target"
    )


if __name__ == "__main__":
    main()
