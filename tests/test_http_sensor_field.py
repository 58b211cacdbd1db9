"""A recording posted as a file takes the accelerometer's data sheet as a form field.

The README promises the data sheet over HTTP; the JSON body had ``sensor`` but a lab
posting its file had no way to give it (``unknown form field 'sensor'``).
"""

from __future__ import annotations

import warnings
from pathlib import Path

import pytest

from serving.app import Limits, create_app
from serving.predictor import Predictor

with warnings.catch_warnings():
    warnings.simplefilter("ignore")
    from fastapi.testclient import TestClient

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "recordings" / "impact_beta45.csv"
SHEET = "lowpass_hz=300,lowpass_order=2"


@pytest.fixture(scope="module")
def client():
    with TestClient(create_app(Predictor.load(), Limits(max_upload_mb=2.0))) as c:
        yield c


def _post(client, route: str, **fields: str):
    files = {"file": ("run.csv", EXAMPLE.read_bytes(), "text/csv")}
    return client.post(route, files=files, data={"natural_frequency_hz": "9.48", **fields})


def test_the_form_field_sensor_is_the_data_sheet(client):
    r = _post(client, "/predict", sensor=SHEET)
    assert r.status_code == 200, r.text
    sheet = r.json()["restoring_force"]["sensor"]
    assert sheet["source"] == "data sheet" and sheet["lowpass_hz"] == 300.0
    r = _post(client, "/log", sensor=SHEET)
    assert r.status_code == 200, r.text
    assert r.json()["chain_undone"]["source"] == "data sheet"


@pytest.mark.parametrize(
    ("sheet", "said"),
    [("lowpass_hz", "form field sensor: 'lowpass_hz' is not KEY=VALUE"),
     ("gain=2", "unknown sensor key(s) gain")],
)  # fmt: skip
def test_a_bad_sheet_is_one_line(client, sheet, said):
    r = _post(client, "/predict", sensor=sheet)
    assert r.status_code == 422 and said in r.json()["error"], r.text
