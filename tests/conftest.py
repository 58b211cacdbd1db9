"""Test set-up: one OpenMP thread (2 shared cores thrash otherwise)."""

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

# The user effects the tests name (user_effects:..., crosscheck_effects:...) are plugins
# loaded explicitly, as a user's are (effect names never import from sys.path).
_HERE = os.path.dirname(os.path.abspath(__file__))
os.environ["STIFFNET_PLUGINS"] = os.pathsep.join(
    [
        os.path.join(_HERE, "user_effects.py"),
        os.path.join(os.path.dirname(_HERE), "benchmarks", "crosscheck_effects.py"),
    ]
)


import pytest  # noqa: E402

#: A tiny labelled dataset shared by the training tests (GBM and CNN): 40
#: trajectories, 2 windows each, three noise levels.
TINY_DATASET = {
    "seed": 7,
    "n_trajectories": 40,
    "shard_size": 20,
    "windows": {"duration_periods": 8, "per_trajectory": 2},
    "sweep": {"fs_ratio": [50, 150], "noise_levels": [0.0, 0.03, 0.12]},
    "solver": {"settle_tolerance": 0.1, "batch_size": 20},
}


@pytest.fixture
def server_log():
    """The warnings the HTTP server writes (``uvicorn.error``), as records, for one test.

    Listened to on that logger itself: a server started in-process earlier configures
    uvicorn's loggers not to propagate to the root logger, where caplog would listen."""
    import logging

    heard: list[logging.LogRecord] = []
    listener = logging.Handler(logging.WARNING)
    listener.emit = heard.append  # type: ignore[method-assign]
    served = logging.getLogger("uvicorn.error")
    level = served.level
    served.addHandler(listener)
    served.setLevel(logging.WARNING)
    yield heard
    served.removeHandler(listener)
    served.setLevel(level)


@pytest.fixture(scope="session")
def tiny_dir(tmp_path_factory):
    from stiffnet.config import validate_config
    from stiffnet.config.sim import SimulationConfig
    from stiffnet.dataset.generate import generate_dataset

    out = tmp_path_factory.mktemp("tiny") / "ds"
    generate_dataset(validate_config(SimulationConfig, TINY_DATASET), out)
    return out
