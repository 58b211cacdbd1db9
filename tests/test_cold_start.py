"""Cold start: what ``import stiffnet.cli`` and ``stiffnet predict`` load (speed: benchmarks/).

The time itself is measured by ``benchmarks/bench_cold_start.py``; these tests pin the
import graph that keeps it short, so a new top-level import of a heavy library fails here.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "recordings" / "impact_beta45.csv"
#: Never loaded by the predictor (the light install has none of the first four).
NEVER_IN_PREDICT = ("torch", "sklearn", "mlflow", "matplotlib", "pandas", "dask", "fastapi")


def _loaded_after(code: str) -> set[str]:
    probe = f"{code}\nimport sys, json\nprint(json.dumps(sorted(sys.modules)))"
    env = dict(os.environ, PYTHONPATH=str(ROOT), OMP_NUM_THREADS="1")
    proc = subprocess.run([sys.executable, "-c", probe], cwd=ROOT, env=env,
                          capture_output=True, text=True, check=True)  # fmt: skip
    return set(json.loads(proc.stdout.strip().splitlines()[-1]))


def test_importing_the_cli_loads_no_science_and_no_heavy_library():
    mods = _loaded_after("import stiffnet.cli")
    heavy = {"numpy", "scipy", "pydantic", "onnxruntime", "pyarrow", *NEVER_IN_PREDICT}
    assert not {m.split(".")[0] for m in mods} & heavy


def test_predict_loads_only_what_it_uses():
    code = (
        "import sys, contextlib, io\n"
        f"sys.argv = ['stiffnet', 'predict', {str(EXAMPLE)!r}]\n"
        "from stiffnet.cli import app\n"
        "with contextlib.redirect_stdout(io.StringIO()):\n"
        "    try:\n        app(prog_name='stiffnet')\n    except SystemExit as e:\n"
        "        assert not e.code, e.code\n"
    )
    mods = _loaded_after(code)
    assert "onnxruntime" in mods and "serving.predictor" in mods  # it did predict
    assert not {m.split(".")[0] for m in mods} & set(NEVER_IN_PREDICT)
