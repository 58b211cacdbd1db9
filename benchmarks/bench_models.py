"""Benchmark the learned stiffness models on one held-out synthetic test set.

One table, by noise level (0, 2, 5, 9 %): accuracy, macro-F1 and beta MAPE of

* **CNN** - ``models/cnn.onnx`` in ONNX Runtime on the canonical delay-embedded
  windows (:func:`stiffnet.features.windows.window_tensor` with the rate,
  periods and delays recorded in the model's metadata, exactly as
  ``training/train.py`` builds them);
* **GBM** - ``models/gbm.onnx`` on the 23 inclination features
  (:class:`training.transformers.InclinationFeatures`, as in training);
* **geometric** - the paper's method alone
  (:func:`training.geometric_baseline.geometric_predictions`: shipped calibration, default
  options; a window it cannot analyse counts as no_contact without a beta, and
  its MAPE is over the contact windows that got a beta, whose fraction is
  reported);
* **MiniRocket** - aeon's MiniRocket transform + ``RidgeClassifierCV`` (class)
  and ``RidgeCV`` on log beta, run by ``benchmarks/minirocket_peer.py`` in a
  separate virtual environment (aeon pins an older numpy), on the same canonical
  windows the CNN sees, trained on the same trajectories of ``data/default``
  the CNN was fitted on (:func:`training.split.trajectory_split` with the seed
  and fractions of ``configs/train/cnn.yaml``; its training and early-stopping
  trajectories, since the ridge models choose their own regularisation by
  internal cross-validation).

The test set is simulated afresh from the default domain with another seed and
discrete noise levels (``benchmarks/configs/model_test_set.yaml``: 2,000
trajectories x 4 windows), so none of its trajectories was seen by the shipped
models. Metrics are :func:`training.metrics.evaluate` (the ones training logs), per
exact noise level, for the levels up to 5 % pooled (the issue's "<= 5 % noise")
and overall; each accuracy has a 95 % bootstrap interval that resamples whole
trajectories (their four windows are not independent). For every CNN the JSON
also holds diagnostics (:func:`cnn_diagnostics`: errors near the class edges,
class taken from the beta head, probabilities averaged per trajectory).

Training times: the CNN's from its model card (``training.seconds``), the
GBM's re-measured here with ``--time-gbm`` (its card does not record it),
MiniRocket's measured by the peer. ONNX Runtime latency and the per-window
preparation cost come from :mod:`bench_onnx_latency` (skip with ``--no-latency``).

Run (about 10 min on 2 busy cores; ``--cache`` makes reruns skip the features,
the geometric method and MiniRocket)::

    python -m venv /work/venvs/bench-aeon && /work/venvs/bench-aeon/bin/pip install aeon
    OMP_NUM_THREADS=1 python benchmarks/bench_models.py \\
        --peer-python /work/venvs/bench-aeon/bin/python --time-gbm \\
        --test-data /tmp/bench_test_set --cache /tmp/bench_cache --out /tmp/bench_models.json

``--quick`` is a smoke run (80 test trajectories, MiniRocket on 400 training
windows, short latency loops). ``--extra-cnn NAME=PATH`` adds a column for
another CNN ONNX file (e.g. a candidate trained into a scratch folder).
"""

from __future__ import annotations

import argparse
import copy
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from stiffnet.config import load_config, load_yaml, validate_config
from stiffnet.config.sim import SimulationConfig
from stiffnet.dataset.generate import generate_dataset
from stiffnet.dataset.store import CARD, Dataset, load_dataset
from stiffnet.features import FEATURE_VERSION
from stiffnet.features.windows import window_tensor
from stiffnet.io_utils import sha256_file, write_json_atomic
from training.config import TrainConfig
from training.geometric_baseline import geometric_predictions
from training.metrics import confusion, evaluate, noise_bin_names
from training.split import trajectory_split
from training.transformers import InclinationFeatures, window_records

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(Path(__file__).resolve().parent))
import bench_onnx_latency  # noqa: E402

DEFAULT_TEST_CONFIG = ROOT / "benchmarks" / "configs" / "model_test_set.yaml"
#: The issue's targets pool the noise levels up to 5 % ("at <= 5 % noise") into this group.
POOLED = "le0.05"
POOLED_MAX_NOISE = 0.05


def say(msg: str) -> None:
    """One progress line on stderr."""
    print(msg, file=sys.stderr, flush=True)


def _merge(base: dict[str, Any], over: dict[str, Any]) -> dict[str, Any]:
    out = copy.deepcopy(base)
    for k, v in over.items():
        out[k] = _merge(out[k], v) if isinstance(v, dict) and isinstance(out.get(k), dict) else v
    return out


def test_config(path: Path, quick: bool = False) -> SimulationConfig:
    """The test set's simulation config: ``base`` YAML deep-merged with ``overrides``.

    Parameters
    ----------
    path : Path
        Benchmark config (``benchmarks/configs/model_test_set.yaml``).
    quick : bool, optional
        Only 80 trajectories (smoke run).

    Returns
    -------
    SimulationConfig
        Validated configuration.
    """
    spec = load_yaml(path)
    base = load_yaml(ROOT / spec["base"]) if spec.get("base") else {}
    data = _merge(base, spec.get("overrides") or {})
    if quick:
        data["n_trajectories"] = 80
    return validate_config(SimulationConfig, data, str(path))


def test_dataset(cfg: SimulationConfig, folder: Path | None, tmp: Path) -> tuple[Dataset, Path]:
    """Simulate the test set (or reuse ``folder`` if it holds the same config).

    Parameters
    ----------
    cfg : SimulationConfig
        Test-set configuration.
    folder : Path or None
        Where to keep the dataset between runs; a temporary folder if None.
    tmp : Path
        Temporary folder of this run.

    Returns
    -------
    Dataset, Path
        The loaded dataset and its folder.
    """
    out = folder or tmp / "test_set"
    want = cfg.model_dump(mode="json")
    if (out / CARD).is_file() and json.loads((out / CARD).read_text()).get("config") == want:
        say(f"test set: reusing {out}")
    else:
        t = time.perf_counter()
        generate_dataset(cfg, out, overwrite=True)
        say(f"test set: simulated {out} in {time.perf_counter() - t:.1f} s")
    return load_dataset(out), out


class Cache:
    """Optional on-disk cache of the slow, model-independent parts (``--cache DIR``).

    Entries are keyed by the test set's card hash plus what else determines them
    (feature version, training data card and peer options), so a changed test set
    or input is recomputed, never reused.
    """

    def __init__(self, folder: Path | None, test_card_sha: str) -> None:
        self.folder = folder
        self.sha = test_card_sha[:16]
        if folder is not None:
            folder.mkdir(parents=True, exist_ok=True)

    def _path(self, name: str, key: str) -> Path | None:
        if self.folder is None:
            return None
        return self.folder / f"{name}-{self.sha}-{key}.npz"

    def get(self, name: str, key: str = "") -> dict[str, Any] | None:
        """The cached arrays (and ``info`` dict), or None."""
        path = self._path(name, key)
        if path is None or not path.is_file():
            return None
        with np.load(path, allow_pickle=False) as z:
            out: dict[str, Any] = {k: z[k] for k in z.files}
        if "info" in out:
            out["info"] = json.loads(str(out["info"]))
        say(f"{name}: from cache {path}")
        return out

    def put(self, name: str, key: str = "", **arrays: Any) -> None:
        """Store arrays (``info`` may be a JSON-able dict); written atomically."""
        path = self._path(name, key)
        if path is None:
            return
        if "info" in arrays:
            arrays["info"] = np.array(json.dumps(arrays["info"]))
        tmp = path.with_name(f".{path.name}.tmp.npz")
        np.savez(tmp, **arrays)
        tmp.replace(path)


def ort_session(path: Path, threads: int = 1) -> Any:
    """ONNX Runtime CPU session with ``threads`` intra-op threads (1 inter-op)."""
    import onnxruntime as ort

    so = ort.SessionOptions()
    so.intra_op_num_threads = threads
    so.inter_op_num_threads = 1
    return ort.InferenceSession(str(path), so, providers=["CPUExecutionProvider"])


def onnx_metadata(sess: Any) -> dict[str, Any]:
    """The model's custom metadata, JSON values decoded."""
    from serving.model import onnx_metadata

    return onnx_metadata(sess)


def cnn_windows(ds: Dataset, meta: dict[str, Any]) -> np.ndarray:
    """Canonical delay-embedded windows, float32 ``(n, C, L)``, as the model was trained on."""
    return window_tensor(
        ds.windows(),
        ds.column("fs_hz"),
        ds.column("natural_frequency_hz"),
        int(meta["canonical_rate"]),
        int(meta["window_periods"]),
        [int(d) for d in meta["delays"]],
    )


def gbm_features(ds: Dataset, meta: dict[str, Any]) -> np.ndarray:
    """The inclination feature matrix, as the GBM family computes it (``training/families/gbm``)."""
    use_fn = bool(meta.get("requires_natural_frequency", True))
    return InclinationFeatures(use_fn, n_jobs=1).fit_transform(window_records(ds))


def run_onnx(sess: Any, x: np.ndarray, batch: int = 256) -> tuple[np.ndarray, np.ndarray]:
    """Class probabilities and log beta of all rows, in batches."""
    name = sess.get_inputs()[0].name
    probs, lbs = [], []
    for i in range(0, len(x), batch):
        out = dict(
            zip(
                [o.name for o in sess.get_outputs()],
                sess.run(None, {name: np.ascontiguousarray(x[i : i + batch], np.float32)}),
                strict=True,
            )
        )
        probs.append(out["probabilities"])
        lbs.append(out["log_beta"][:, 0])
    return np.concatenate(probs), np.concatenate(lbs)


def by_level(
    y: np.ndarray,
    pred: np.ndarray,
    beta: np.ndarray,
    beta_hat: np.ndarray,
    noise: np.ndarray,
    names: list[str],
    levels: list[float],
) -> dict[str, dict[str, float]]:
    """:func:`training.metrics.evaluate` regrouped as ``{level or "all": {metric: value}}``."""
    m = evaluate(y, pred, beta, beta_hat, noise, names, levels)
    out: dict[str, dict[str, float]] = {"all": {k: v for k, v in m.items() if "/" not in k}}
    out["all"].update({k: v for k, v in m.items() if k.startswith("recall/")})
    for lev, bin_name in zip(levels, noise_bin_names(levels), strict=False):
        sub = {k.split("/", 1)[1]: v for k, v in m.items() if k.startswith(bin_name + "/")}
        if sub:
            out[f"{lev:g}"] = sub
    low = noise <= POOLED_MAX_NOISE + 1e-12
    if low.any() and not low.all():
        ml = evaluate(y[low], pred[low], beta[low], beta_hat[low], noise[low], names, levels)
        out[POOLED] = {k: v for k, v in ml.items() if "/" not in k}
    return out


def accuracy_ci(
    y: np.ndarray,
    pred: np.ndarray,
    trajectory: np.ndarray,
    noise: np.ndarray,
    levels: list[float],
    n_boot: int = 1000,
    seed: int = 0,
) -> dict[str, list[float]]:
    """95 % bootstrap interval of the accuracy per noise level, resampling whole trajectories.

    The windows of one trajectory share its parameters, so they are not
    independent; resampling trajectories gives an honest interval.
    """
    rng = np.random.default_rng(seed)
    out = {}
    groups = [("all", np.ones(y.size, bool)), (POOLED, noise <= POOLED_MAX_NOISE + 1e-12)]
    for key, m in groups + [(f"{lev:g}", np.isclose(noise, lev)) for lev in levels]:
        if not m.any():
            continue
        ids, inv = np.unique(trajectory[m], return_inverse=True)
        hits = np.bincount(inv, weights=(y[m] == pred[m]).astype(float), minlength=ids.size)
        count = np.bincount(inv, minlength=ids.size).astype(float)
        b = rng.integers(0, ids.size, size=(n_boot, ids.size))
        acc = hits[b].sum(1) / count[b].sum(1)
        out[key] = [round(float(v), 4) for v in np.quantile(acc, [0.025, 0.975])]
    return out


def cnn_diagnostics(
    ds: Dataset,
    proba: np.ndarray,
    log_beta: np.ndarray,
    edges: list[float],
    levels: list[float],
) -> dict[str, Any]:
    """Why the CNN errs: distance of the errors to the class edges, and two decision rules.

    * ``errors_near_edge``: share of the contact-class errors whose true beta is
      within 2 / 5 % (in log) of a class edge (15, 35, 60 by default);
    * ``accuracy_class_from_beta``: accuracy if the class of a window the CNN
      calls contact is taken from its beta head (the bin of the predicted beta)
      instead of the class head;
    * ``accuracy_trajectory_mean``: accuracy if the probabilities of the
      windows of one trajectory are averaged (test-time averaging over the four
      consecutive windows of a recording).
    """
    y, beta, noise = ds.column("label"), ds.column("beta"), ds.column("noise")
    traj = ds.column("trajectory")
    pred = proba.argmax(1)
    contact = y != 0
    e = np.asarray(edges, dtype=np.float64)
    dist = np.min(np.abs(np.log(beta[:, None] / e[None, :])), axis=1)
    err = (pred != y) & contact & (pred != 0)
    bh = np.exp(log_beta.astype(np.float64))
    r = np.log(bh[contact] / beta[contact])
    from_beta = np.where(pred == 0, 0, 1 + np.searchsorted(e, bh))
    ids, inv = np.unique(traj, return_inverse=True)
    mean_p = np.zeros((ids.size, proba.shape[1]))
    np.add.at(mean_p, inv, proba)
    traj_pred = mean_p.argmax(1)[inv]
    out: dict[str, Any] = {
        "n_errors": int((pred != y).sum()),
        "n_errors_involving_no_contact": int(((pred != y) & ((y == 0) | (pred == 0))).sum()),
        "n_errors_adjacent_class": int((err & (np.abs(pred - y) == 1)).sum()),
        "errors_near_edge": {
            f"{int(100 * t)}%": round(float(np.mean(dist[err] < t)), 3) if err.any() else None
            for t in (0.02, 0.05)
        },
        "contact_windows_near_edge": {
            f"{int(100 * t)}%": round(float(np.mean(dist[contact] < t)), 3) for t in (0.02, 0.05)
        },
        # robust spread (1.4826 MAD) of log(beta_hat / beta) on the contact windows
        "beta_log_residual_sigma": round(float(1.4826 * np.median(np.abs(r - np.median(r)))), 4),
    }
    for key, rule in (("accuracy_class_from_beta", from_beta), ("accuracy_trajectory_mean",
                                                                 traj_pred)):  # fmt: skip
        out[key] = {"all": round(float(np.mean(rule == y)), 4)}
        for lev in levels:
            m = np.isclose(noise, lev)
            if m.any():
                out[key][f"{lev:g}"] = round(float(np.mean(rule[m] == y[m])), 4)
    return out


def training_split(data_dir: Path, train_config: Path) -> tuple[Dataset, np.ndarray]:
    """``data/default`` and the mask of the windows the CNN was fitted on (train + val)."""
    cfg = load_config(TrainConfig, train_config)
    ds = load_dataset(data_dir)
    sp = trajectory_split(
        ds.column("trajectory"),
        cfg.test_fraction,
        cfg.calibration_fraction,
        cfg.cnn.validation_fraction,
        cfg.seed,
    )
    return ds, sp.train | sp.val


def run_minirocket(
    peer_python: str,
    train_x: np.ndarray,
    train_y: np.ndarray,
    train_log_beta: np.ndarray,
    test_x: np.ndarray,
    tmp: Path,
    n_jobs: int,
) -> dict[str, Any]:
    """Export the windows as .npy, run ``minirocket_peer.py`` in the peer venv, read its output.

    Returns
    -------
    dict
        ``pred`` (class indices), ``log_beta`` (test), and the peer's ``info``
        (versions, fit and predict seconds).
    """
    folder = tmp / "peer"
    folder.mkdir(exist_ok=True)
    for name, arr in (
        ("train_x", train_x),
        ("train_y", train_y.astype(np.int64)),
        ("train_log_beta", train_log_beta.astype(np.float64)),
        ("test_x", test_x),
    ):
        np.save(folder / f"{name}.npy", arr)
    cmd = [
        peer_python,
        str(Path(__file__).resolve().parent / "minirocket_peer.py"),
        str(folder),
        "--n-jobs",
        str(n_jobs),
    ]
    say(f"MiniRocket: {' '.join(cmd)}")
    env = {**os.environ, "OMP_NUM_THREADS": str(n_jobs), "NUMBA_NUM_THREADS": str(n_jobs)}
    subprocess.run(cmd, check=True, env=env)
    info = json.loads((folder / "peer_result.json").read_text())
    return {
        "pred": np.load(folder / "test_pred.npy"),
        "log_beta": np.load(folder / "test_log_beta.npy"),
        "info": info,
    }


def time_gbm(data_dir: Path, train_config: Path, cache: Path | None, threads: int) -> dict:
    """Re-measure the GBM's training (features of ``data/default``, then :func:`fit_gbm`).

    The fit runs with ``threads`` OpenMP threads (threadpoolctl); the features
    are computed in this process (one core) or read from ``cache``.
    """
    from threadpoolctl import threadpool_limits

    from training.families.gbm.model import fit_gbm

    cfg = load_config(TrainConfig, train_config)
    ds = load_dataset(data_dir)
    t = time.perf_counter()
    if cache is not None and cache.is_file():
        X = np.load(cache)
        t_feat = None
    else:
        X = InclinationFeatures(cfg.use_natural_frequency, n_jobs=1).fit_transform(
            window_records(ds)
        )
        t_feat = time.perf_counter() - t
        if cache is not None:
            np.save(cache, X)
    sp = trajectory_split(
        ds.column("trajectory"),
        cfg.test_fraction,
        cfg.calibration_fraction,
        cfg.gbm.validation_fraction,
        cfg.seed,
    )
    with threadpool_limits(threads):
        t = time.perf_counter()
        clf, reg = fit_gbm(X, ds.column("label"), ds.column("beta"), sp, cfg.gbm, cfg.seed)
        t_fit = time.perf_counter() - t
    return {
        "fit_s": round(t_fit, 2),
        "features_s": None if t_feat is None else round(t_feat, 2),
        "n_windows_features": len(ds),
        "n_train_windows": int(sp.train.sum()),
        "threads": threads,
        "n_iter": {"classifier": int(clf.n_iter_), "regressor": int(reg.n_iter_)},
    }


def markdown_table(result: dict[str, Any]) -> str:
    """The accuracy table: one row per model and noise level."""
    levels = result["levels"]
    lines = [
        "| model | noise | windows | accuracy | (95 % CI) | macro-F1 | β MAPE |",
        "| --- | --- | --- | --- | --- | --- | --- |",
    ]
    for model, m in result["models"].items():
        for lev in [*levels, POOLED, "all"]:
            r = m["metrics"].get(lev)
            if r is None:
                continue
            mape = r.get("beta_mape")
            frac = r.get("beta_estimated_fraction", 1.0)
            mape_s = "—" if mape is None else f"{mape:.3f}"
            if mape is not None and frac < 0.999:
                mape_s += f" ({frac:.0%} est.)"
            label = {"all": "all", POOLED: "≤ 5 % (pooled)"}.get(lev) or f"{100 * float(lev):g} %"
            ci = m.get("accuracy_ci95", {}).get(lev)
            ci_s = "" if ci is None else f"{ci[0]:.3f}–{ci[1]:.3f}"
            lines.append(
                f"| {model} | {label} | {int(r['n'])} | {r['accuracy']:.3f} | {ci_s} | "
                f"{r['macro_f1']:.3f} | {mape_s} |"
            )
    return "\n".join(lines)


def targets(result: dict[str, Any], model: str = "CNN") -> dict[str, bool]:
    """The issue's targets, checked on the table for one CNN column.

    Accuracy >= 97 % at each level <= 5 % (and pooled) and >= 92 % above;
    accuracy >= MiniRocket's at every level; beta MAPE <= 8 % at <= 5 % noise.
    """
    cnn = result["models"][model]["metrics"]
    peer = result["models"].get("MiniRocket", {}).get("metrics")
    out: dict[str, bool] = {}
    for lev in [*result["levels"], POOLED]:
        if lev not in cnn:
            continue
        acc = cnn[lev]["accuracy"]
        low = lev == POOLED or float(lev) <= POOLED_MAX_NOISE
        need = 0.97 if low else 0.92
        out[f"accuracy@{lev}>={need}"] = bool(acc >= need)
        if low:
            out[f"beta_mape@{lev}<=0.08"] = bool(cnn[lev].get("beta_mape", 1) <= 0.08)
        if peer and lev in peer and lev != POOLED:
            out[f">=minirocket@{lev}"] = bool(acc >= peer[lev]["accuracy"])
    return out


def main(argv: list[str] | None = None) -> int:
    """Command-line entry point."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, required=True, help="JSON result (written atomically)")
    ap.add_argument("--config", type=Path, default=DEFAULT_TEST_CONFIG, help="test-set config")
    ap.add_argument(
        "--test-data",
        type=Path,
        default=None,
        help="keep/reuse the simulated test set here (default: temporary)",
    )
    ap.add_argument("--models", type=Path, default=ROOT / "models")
    ap.add_argument(
        "--data",
        type=Path,
        default=ROOT / "data" / "default",
        help="training dataset of the shipped models (MiniRocket's training split)",
    )
    ap.add_argument(
        "--train-config",
        type=Path,
        default=ROOT / "configs" / "train" / "cnn.yaml",
        help="the CNN's training config (split seed and fractions)",
    )
    ap.add_argument(
        "--extra-cnn",
        action="append",
        default=[],
        metavar="NAME=PATH",
        help="another CNN ONNX file to evaluate as an extra column",
    )
    ap.add_argument(
        "--peer-python",
        default=None,
        help="python of a venv with aeon (MiniRocket column skipped without it)",
    )
    ap.add_argument("--peer-jobs", type=int, default=1, help="MiniRocket threads")
    ap.add_argument(
        "--peer-channels",
        choices=["all", "first"],
        default="all",
        help="MiniRocket input: all delay channels the CNN sees, or the canonical window only",
    )
    ap.add_argument("--time-gbm", action="store_true", help="re-measure the GBM's training time")
    ap.add_argument("--gbm-threads", type=int, default=2, help="OpenMP threads of that fit")
    ap.add_argument(
        "--feature-cache",
        type=Path,
        default=None,
        help=".npy cache of data/default's features for --time-gbm",
    )
    ap.add_argument(
        "--cache",
        type=Path,
        default=None,
        help="folder caching features, geometric and MiniRocket results between runs",
    )
    ap.add_argument("--no-latency", action="store_true", help="skip the ONNX latency part")
    ap.add_argument("--n-jobs", type=int, default=1, help="processes for the geometric method")
    ap.add_argument("--quick", action="store_true", help="small smoke run")
    args = ap.parse_args(argv)

    t_all = time.perf_counter()
    cfg = test_config(args.config, args.quick)
    levels = [f"{x:g}" for x in cfg.sweep.noise_levels or []]
    if not levels:
        ap.error(f"{args.config} must set sweep.noise_levels")
    with tempfile.TemporaryDirectory(prefix="bench_models_") as tmp_name:
        tmp = Path(tmp_name)
        ds, test_dir = test_dataset(cfg, args.test_data, tmp)
        cache = Cache(args.cache, sha256_file(test_dir / CARD))
        names = ds.class_names
        y, beta, noise = ds.column("label"), ds.column("beta"), ds.column("noise")
        lev_f = [float(v) for v in levels]
        result: dict[str, Any] = {
            "test_set": {
                "config": str(args.config),
                "seed": cfg.seed,
                "n_trajectories": cfg.n_trajectories,
                "n_windows": len(ds),
                "class_balance": ds.card.get("class_balance"),
                "windows_per_level": {
                    lv: int(np.sum(np.isclose(noise, float(lv)))) for lv in levels
                },
            },
            "levels": levels,
            "models": {},
            "confusion": {},
            "class_names": names,
        }

        def add(model: str, pred: np.ndarray, beta_hat: np.ndarray, **extra: Any) -> None:
            result["models"][model] = {
                "metrics": by_level(y, pred, beta, beta_hat, noise, names, lev_f),
                **extra,
            }
            result["models"][model]["accuracy_ci95"] = accuracy_ci(
                y, pred, ds.column("trajectory"), noise, lev_f
            )
            result["confusion"][model] = confusion(y, pred, len(names)).tolist()
            acc = result["models"][model]["metrics"]["all"]["accuracy"]
            say(f"{model}: accuracy {acc:.3f}")

        # CNN (shipped, plus any extra candidates)
        cnn_files = [("CNN", args.models / "cnn.onnx")]
        for spec in args.extra_cnn:
            name, _, path = spec.partition("=")
            cnn_files.append((name, Path(path)))
        extra_names = [name for name, _ in cnn_files[1:]]
        xw_cache: dict[tuple, np.ndarray] = {}
        for model, path in cnn_files:
            sess = ort_session(path)
            meta = onnx_metadata(sess)
            key = (meta["canonical_rate"], meta["window_periods"], tuple(meta["delays"]))
            if key not in xw_cache:
                t = time.perf_counter()
                xw_cache[key] = cnn_windows(ds, meta)
                say(f"canonical windows {xw_cache[key].shape}: {time.perf_counter() - t:.1f} s")
            proba, lb = run_onnx(sess, xw_cache[key])
            add(model, proba.argmax(1), np.exp(lb.astype(np.float64)), file=str(path))
            result["models"][model]["diagnostics"] = cnn_diagnostics(
                ds, proba, lb, [c.beta[0] for c in cfg.classes[1:]], lev_f
            )
        xw = xw_cache[next(iter(xw_cache))]

        # GBM
        sess = ort_session(args.models / "gbm.onnx")
        t = time.perf_counter()
        hit = cache.get("gbm_features", f"v{FEATURE_VERSION}")
        if hit is None:
            feats = gbm_features(ds, onnx_metadata(sess))
            cache.put("gbm_features", f"v{FEATURE_VERSION}", x=feats)
            say(f"features {feats.shape}: {time.perf_counter() - t:.1f} s")
        else:
            feats = hit["x"]
        proba, lb = run_onnx(sess, feats)
        add("GBM", proba.argmax(1), np.exp(lb.astype(np.float64)), file="models/gbm.onnx")

        # geometric method alone
        t = time.perf_counter()
        calib = ROOT / "models" / "geometric_calibration.json"
        g_key = sha256_file(calib)[:12] if calib.is_file() else "nocal"
        hit = cache.get("geometric", g_key)
        if hit is None:
            g_cls, g_beta = geometric_predictions(
                [np.asarray(w, np.float64) for w in ds.windows()], ds.column("fs_hz"), args.n_jobs
            )
            g_pred = np.array([names.index(c) if c in names else 0 for c in g_cls])
            cache.put("geometric", g_key, pred=g_pred, beta=g_beta)
            say(f"geometric: {time.perf_counter() - t:.1f} s")
        else:
            g_pred, g_beta = hit["pred"], hit["beta"]
        add("geometric", g_pred, g_beta)

        # MiniRocket in its own venv
        p_key = "-".join(
            [
                sha256_file(args.data / CARD)[:12],
                sha256_file(args.train_config)[:8],
                sha256_file(args.models / "cnn.onnx")[:8],
                f"{args.peer_channels}-q{int(args.quick)}",
            ]
        )
        hit = cache.get("minirocket", p_key) if args.peer_python else None
        if hit is not None:
            add("MiniRocket", hit["pred"], np.exp(hit["log_beta"]), peer=hit["info"])
        elif args.peer_python:
            tr_ds, mask = training_split(args.data, args.train_config)
            idx = np.flatnonzero(mask)
            if args.quick:
                idx = np.random.default_rng(0).choice(idx, 400, replace=False)
            sub = Dataset(tr_ds.table.take(idx), tr_ds.card)
            meta = onnx_metadata(ort_session(args.models / "cnn.onnx"))
            t = time.perf_counter()
            train_x = cnn_windows(sub, meta)
            say(f"MiniRocket training windows {train_x.shape}: {time.perf_counter() - t:.1f} s")
            tr_y, tr_beta = sub.column("label"), sub.column("beta")
            tr_lb = np.where(tr_y != 0, np.log(np.where(tr_y != 0, tr_beta, 1.0)), np.nan)
            ch = slice(None) if args.peer_channels == "all" else slice(0, 1)
            peer = run_minirocket(
                args.peer_python, train_x[:, ch], tr_y, tr_lb, xw[:, ch], tmp, args.peer_jobs
            )
            cache.put("minirocket", p_key, **peer)
            add("MiniRocket", peer["pred"], np.exp(peer["log_beta"]), peer=peer["info"])
        else:
            say("MiniRocket: skipped (no --peer-python; see docs/model_benchmark.md)")
            result["minirocket_skipped"] = "no --peer-python given"

    # training times
    cnn_card = json.loads((args.models / "cnn.card.json").read_text())
    tr = cnn_card.get("training", {})
    times: dict[str, Any] = {
        "CNN": {
            "fit_s": tr.get("seconds"),
            "source": "models/cnn.card.json training.seconds (torch.set_num_threads(1) in "
            "training/train.py)",
            "epochs": tr.get("epochs"),
            "best_epoch": tr.get("best_epoch"),
        }
    }
    for name, path in cnn_files[1:]:
        card_path = path.with_suffix(".card.json")
        if card_path.is_file():
            tr_x = json.loads(card_path.read_text()).get("training", {})
            times[name] = {
                "fit_s": tr_x.get("seconds"),
                "source": f"{card_path} training.seconds",
                "epochs": tr_x.get("epochs"),
                "best_epoch": tr_x.get("best_epoch"),
            }
    if args.time_gbm:
        say("GBM: re-measuring its training time ...")
        times["GBM"] = {**time_gbm(args.data, args.train_config.parent / "gbm.yaml",
                                   args.feature_cache, args.gbm_threads),
                        "source": "re-measured by this script"}  # fmt: skip
        say(f"GBM fit: {times['GBM']['fit_s']} s")
    if "MiniRocket" in result["models"]:
        info = result["models"]["MiniRocket"]["peer"]
        times["MiniRocket"] = {
            "fit_s": info["fit_s"],
            "source": "measured by benchmarks/minirocket_peer.py",
            "n_train_windows": info["n_train"],
            "threads": info["n_jobs"],
        }
    result["training_time"] = times

    if not args.no_latency:
        say("latency ...")
        result["latency"] = bench_onnx_latency.measure(
            args.models / "cnn.onnx", args.models / "gbm.onnx", args.data, quick=args.quick
        )
    result["targets"] = {
        m: targets(result, m) for m in result["models"] if m == "CNN" or m in extra_names
    }
    result["seconds"] = round(time.perf_counter() - t_all, 1)
    result["load_average"] = os.getloadavg()
    result["omp_num_threads"] = os.environ.get("OMP_NUM_THREADS")

    table = markdown_table(result)
    result["markdown"] = table
    write_json_atomic(args.out, result)
    print(table)
    print()
    for m, tg in result["targets"].items():
        for k, v in tg.items():
            print(f"target {m} {k}: {'met' if v else 'MISSED'}")
    for model, t in times.items():
        print(f"training time {model}: {t.get('fit_s')} s ({t['source']})")
    if "latency" in result:
        print(bench_onnx_latency.markdown(result["latency"]))
    say(f"wrote {args.out} ({result['seconds']} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
