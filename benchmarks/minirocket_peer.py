"""MiniRocket peer of ``benchmarks/bench_models.py``: runs in a separate venv with aeon.

aeon pins an older numpy than stiffnet, so this script imports only numpy and
aeon (plus the scikit-learn aeon depends on) and talks to the benchmark through
``.npy`` files in one folder:

* in: ``train_x.npy`` float32 ``(n, C, L)`` (the canonical windows the CNN sees),
  ``train_y.npy`` int class indices, ``train_log_beta.npy`` float (NaN for
  no-contact windows), ``test_x.npy``;
* out: ``test_pred.npy`` (class indices), ``test_log_beta.npy`` and
  ``peer_result.json`` (versions, sizes, seconds).

Models: the MiniRocket transform (10,000 kernels, aeon's defaults; multivariate
input is handled natively) followed by aeon's default ``MiniRocketClassifier``
head - ``StandardScaler(with_mean=False)`` and ``RidgeClassifierCV`` over
``logspace(-3, 3, 10)`` - for the class, and the same scaler with ``RidgeCV``
over the same alphas on log beta of the contact windows for beta. One
transform serves both heads. ``fit_s`` is transform-fit + transform of the
training windows + both ridge fits, after a warm-up on four windows that pays
numba's JIT compilation (``jit_compile_s``, reported apart); ``predict_s`` the
test transform and both predictions.

Run (normally started by bench_models.py)::

    /work/venvs/bench-aeon/bin/python benchmarks/minirocket_peer.py FOLDER [--n-jobs 1]
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import aeon
import numpy as np
from aeon.transformations.collection.convolution_based import MiniRocket
from sklearn.linear_model import RidgeClassifierCV, RidgeCV
from sklearn.pipeline import make_pipeline
from sklearn.preprocessing import StandardScaler

ALPHAS = np.logspace(-3, 3, 10)


def fit_predict(
    train_x: np.ndarray,
    train_y: np.ndarray,
    train_log_beta: np.ndarray,
    test_x: np.ndarray,
    n_jobs: int = 1,
    seed: int = 0,
) -> tuple[np.ndarray, np.ndarray, dict]:
    """Fit MiniRocket + ridge heads on the training windows and predict the test windows.

    Parameters
    ----------
    train_x, test_x : numpy.ndarray
        Windows ``(n, C, L)``.
    train_y : numpy.ndarray
        Class indices of the training windows.
    train_log_beta : numpy.ndarray
        log beta of the training windows (NaN where there is no contact).
    n_jobs : int, optional
        MiniRocket threads.
    seed : int, optional
        Random state of the transform.

    Returns
    -------
    pred, log_beta, info
        Test class indices, test log beta and timings.
    """
    t0 = time.perf_counter()
    MiniRocket(n_jobs=n_jobs, random_state=seed).fit_transform(train_x[:4].astype(np.float32))
    t_compile = time.perf_counter() - t0  # numba JIT compilation, not counted as training

    t0 = time.perf_counter()
    rocket = MiniRocket(n_jobs=n_jobs, random_state=seed)
    z = rocket.fit_transform(train_x.astype(np.float32))
    t_transform = time.perf_counter() - t0
    clf = make_pipeline(StandardScaler(with_mean=False), RidgeClassifierCV(alphas=ALPHAS))
    clf.fit(z, train_y)
    contact = np.isfinite(train_log_beta)
    reg = make_pipeline(StandardScaler(with_mean=False), RidgeCV(alphas=ALPHAS))
    reg.fit(z[contact], train_log_beta[contact])
    fit_s = time.perf_counter() - t0

    t1 = time.perf_counter()
    zt = rocket.transform(test_x.astype(np.float32))
    pred = clf.predict(zt).astype(np.int64)
    log_beta = reg.predict(zt).astype(np.float64)
    predict_s = time.perf_counter() - t1
    info = {
        "aeon": aeon.__version__,
        "numpy": np.__version__,
        "n_train": int(len(train_x)),
        "n_test": int(len(test_x)),
        "input_shape": list(train_x.shape[1:]),
        "n_features": int(z.shape[1]),
        "alpha_classifier": float(clf[-1].alpha_),
        "alpha_regressor": float(reg[-1].alpha_),
        "n_jobs": n_jobs,
        "jit_compile_s": round(t_compile, 2),
        "transform_fit_s": round(t_transform, 2),
        "fit_s": round(fit_s, 2),
        "predict_s": round(predict_s, 2),
        "predict_ms_per_window": round(1e3 * predict_s / max(1, len(test_x)), 3),
    }
    return pred, log_beta, info


def main(argv: list[str] | None = None) -> int:
    """Command-line entry point."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("folder", type=Path, help="folder with the input .npy files")
    ap.add_argument("--n-jobs", type=int, default=1)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    f = args.folder
    pred, log_beta, info = fit_predict(
        np.load(f / "train_x.npy"),
        np.load(f / "train_y.npy"),
        np.load(f / "train_log_beta.npy"),
        np.load(f / "test_x.npy"),
        args.n_jobs,
        args.seed,
    )
    np.save(f / "test_pred.npy", pred)
    np.save(f / "test_log_beta.npy", log_beta)
    tmp = f / ".peer_result.json.tmp"
    tmp.write_text(json.dumps(info, indent=2))
    tmp.replace(f / "peer_result.json")
    print(
        f"MiniRocket: {info['n_train']} training windows {info['input_shape']}, "
        f"fit {info['fit_s']} s, predict {info['predict_s']} s"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
