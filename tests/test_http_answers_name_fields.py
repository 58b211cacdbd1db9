"""An HTTP answer names what an HTTP client can send (a field), never a command-line option.

The readers and the predictor share their refusals with the CLI; where the user gives a
value differs (``--fn`` on the command line, ``natural_frequency_hz`` over HTTP), and a
client told to pass ``--channel INDEX`` has nothing to type.
"""

from __future__ import annotations

import io
import re
import warnings
from pathlib import Path

import numpy as np
import pytest
from scipy.io import wavfile

from serving.app import Limits, create_app
from serving.predictor import Predictor, fn_unknown
from stiffnet.inputs import HINT_CONTEXT, sensor_given
from stiffnet.recordings import read_recording

with warnings.catch_warnings():
    warnings.simplefilter("ignore")
    from fastapi.testclient import TestClient

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "recordings" / "impact_beta45.csv"
#: A command-line option in a message: ``--fn``, ``--channel INDEX``, ``(--time-unit ms``.
OPTION = re.compile(r"(^|[\s(;,])--[a-z]")


@pytest.fixture(scope="module")
def client():
    with TestClient(create_app(Predictor.load(), Limits(max_upload_mb=2.0))) as c:
        yield c


def _refusal(r) -> str:
    assert r.status_code == 422, (r.status_code, r.text)
    message = r.json()["error"]
    assert not OPTION.search(message), message
    return message


def test_no_natural_frequency_names_the_field(client):
    samples = read_recording(EXAMPLE).accel.tolist()
    for route in ("/predict", "/log"):
        message = _refusal(client.post(route, json={"samples": samples, "fs_hz": 1000.0}))
        assert "natural frequency unknown" in message and "natural_frequency_hz" in message
    files = {"file": ("run.csv", EXAMPLE.read_bytes(), "text/csv")}
    message = _refusal(client.post("/predict", files=files))
    assert "the field natural_frequency_hz" in message


def test_a_multichannel_upload_names_the_channel_field(client):
    x = read_recording(EXAMPLE).accel.astype(np.float32)
    buf = io.BytesIO()
    wavfile.write(buf, 1000, np.column_stack([x, 0.5 * x]))
    files = {"file": ("two.wav", buf.getvalue(), "audio/wav")}
    message = _refusal(client.post("/predict", files=files, data={"natural_frequency_hz": "9.48"}))
    assert "choose one with the field channel" in message


def test_a_time_column_in_ms_names_the_time_unit_field(client):
    rec = read_recording(EXAMPLE)
    t = np.arange(rec.accel.size) / rec.fs_hz * 1e3  # ms, read as seconds
    text = "t,accel\n" + "".join(f"{a:.6f},{b:.6e}\n" for a, b in zip(t, rec.accel, strict=True))
    files = {"file": ("ms.csv", text.encode(), "text/csv")}
    message = _refusal(client.post("/predict", files=files, data={"natural_frequency_hz": "9.48"}))
    assert "the field time_unit=ms" in message


@pytest.mark.parametrize(
    ("where", "fn_text", "sensor_text"),
    [
        ("cli", "--fn HZ", "--sensor"),
        ("manifest", "the manifest's column natural_frequency_hz", "the manifest's column sensor"),
        ("http", "the field natural_frequency_hz", "the field sensor"),
    ],
)
def test_each_place_gets_its_own_words(where, fn_text, sensor_text):
    token = HINT_CONTEXT.set(where)
    try:
        assert fn_text in fn_unknown() and sensor_given() == sensor_text
    finally:
        HINT_CONTEXT.reset(token)


@pytest.mark.parametrize(
    ("field", "value"), [("fs_hz", "1000 Hz"), ("natural_frequency_hz", "9.48Hz")]
)
def test_a_form_number_written_with_its_unit_says_to_send_the_number_alone(client, field, value):
    """'1000 Hz' in the form field fs_hz was "is not a number" with nothing said of why, where
    a sidecar's and a manifest's '9.48 Hz' say to write the number alone."""
    fields = {"natural_frequency_hz": "9.48", field: value}
    files = {"file": ("run.csv", EXAMPLE.read_bytes(), "text/csv")}
    message = _refusal(client.post("/predict", files=files, data=fields))
    assert message == (
        f"form field {field}: {value!r} is not a number (the number alone: the name carries "
        "the unit)"
    )


def test_a_form_number_with_a_decimal_comma_says_to_write_a_point(client):
    """'9,48' in the form field natural_frequency_hz (a German locale's decimal comma) was
    "is not a number" with nothing said of why."""
    fields = {"natural_frequency_hz": "9,48"}
    files = {"file": ("run.csv", EXAMPLE.read_bytes(), "text/csv")}
    message = _refusal(client.post("/predict", files=files, data=fields))
    assert message == (
        "form field natural_frequency_hz: '9,48' is not a number (a comma in a number: write "
        "the decimal point '.' and no thousands separator)"
    )
