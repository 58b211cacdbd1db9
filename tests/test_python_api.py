"""The Python API for notebooks: docs/python_api.md's example runs as written."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "python_api.md"


def doc_example() -> str:
    """The first python block under the page's "Example" heading."""
    text = DOC.read_text()
    section = text[text.index("## Example") :]
    return re.search(r"```python\n(.*?)```", section, re.S).group(1)


def test_the_documented_example_runs_and_imports_no_training_stack():
    code = doc_example() + (
        "\nimport sys\n"
        "assert not {'torch', 'sklearn', 'mlflow'} & set(sys.modules), sorted(sys.modules)\n"
        "from serving.predictor import predict_recording\n"
        "ref = predict_recording('examples/recordings/impact_beta45.csv')\n"
        "assert r2 == ref, 'the notebook gets what the command line gets'\n"
        "assert len(betas) == 2 and all(b is not None for b in betas)\n"
        "assert times.size == beta_t.size == len(log['points']) > 0\n"
    )
    done = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True,
                          text=True, timeout=300)  # fmt: skip
    assert done.returncode == 0, done.stderr[-3000:]
    assert "hard" in done.stdout
    assert "refused: natural frequency unknown" in done.stdout


def test_the_api_is_the_predictors_own_object():
    import serving.predictor
    import stiffnet.api

    assert stiffnet.api.Predictor is serving.predictor.Predictor
    assert set(stiffnet.api.__all__) <= set(dir(stiffnet.api))
