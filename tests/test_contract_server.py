"""The server under abuse: per-client limits, header and idle timeouts, JSON for every
error (uvicorn's own 400s and a foreign CORS preflight included), samples counted
before parsing, unknown form fields refused, an access log line per request.

The live tests start `stiffnet serve` on 127.0.0.1 and stop it; an "other client" is
the loopback address 127.0.0.2 (the server tells clients apart by address).
"""

from __future__ import annotations

import json
import socket
import time

import httpx
import pytest
from live_server import serving
from test_contract import ROOT

from stiffnet import __version__

MODEL = ROOT / "models" / "gbm.onnx"
HEAD = (b"POST /predict HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: application/json\r\n"
        b"Content-Length: 100000\r\n\r\n")  # fmt: skip


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    log = tmp_path_factory.mktemp("serve") / "stderr.txt"
    args = ["--model", str(MODEL), "--header-timeout-s", "1.5", "--body-idle-s", "1.5",
            "--body-timeout-s", "20"]  # fmt: skip
    with open(log, "wb") as err, serving(*args, stderr=err) as port:
        yield port, log


def _connect(port: int, source: str = "127.0.0.1") -> socket.socket:
    return socket.create_connection(("127.0.0.1", port), timeout=10, source_address=(source, 0))


def _read_all(s: socket.socket) -> bytes:
    chunks = []
    try:
        while chunk := s.recv(65536):
            chunks.append(chunk)
    except OSError:
        pass
    finally:
        s.close()
    return b"".join(chunks)


def _json_body(reply: bytes) -> dict:
    head, _, body = reply.partition(b"\r\n\r\n")
    assert b"application/json" in head.lower(), reply[:300]
    return json.loads(body)


def test_trickled_header_lines_are_cut_off_with_json_408(server):
    port, _ = server
    s = _connect(port)
    s.sendall(b"POST /predict HTTP/1.1\r\nHost: 127.0.0.1\r\n")
    t = time.monotonic()
    try:
        for i in range(8):  # a header line every 0.5 s: the head never ends
            time.sleep(0.5)
            s.sendall(f"X-Slow-{i}: 1\r\n".encode())
    except OSError:
        pass  # closed by the server: what we want
    reply = _read_all(s)
    assert reply.startswith(b"HTTP/1.1 408"), reply[:200]
    assert "request head" in _json_body(reply)["error"]
    assert time.monotonic() - t < 4.5  # --header-timeout-s 1.5


def test_malformed_content_length_is_a_json_400(server):
    port, _ = server
    s = _connect(port)
    s.sendall(b"POST /predict HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Length: 12abc\r\n\r\n{}")
    reply = _read_all(s)
    assert reply.startswith(b"HTTP/1.1 400") and "malformed" in _json_body(reply)["error"]


def test_stalled_uploads_lock_out_only_their_client(server):
    """One address holding its share of stalled small uploads gets 429; another is served."""
    from serving.app import MAX_READERS_PER_CLIENT

    port, log = server
    stalled = []
    for _ in range(MAX_READERS_PER_CLIENT):
        s = _connect(port, "127.0.0.2")
        s.sendall(HEAD + b'{"samples": [1')  # and then nothing more
        stalled.append(s)
    time.sleep(0.3)
    s = _connect(port, "127.0.0.2")
    s.sendall(HEAD + b'{"samples": [1')
    reply = _read_all(s)
    assert reply.startswith(b"HTTP/1.1 429") and "this client" in _json_body(reply)["error"]
    small = {"samples": [0.0, 1.0] * 200, "fs_hz": 1000}
    r = httpx.post(f"http://127.0.0.1:{port}/predict", json=small, timeout=10)
    assert r.status_code == 422 and set(r.json()) == {"error"}  # served (too short), not 429
    t = time.monotonic()
    replies = [_read_all(s) for s in stalled]  # --body-idle-s 1.5: each freed early
    assert all(r.startswith(b"HTTP/1.1 408") for r in replies), replies[0][:200]
    assert time.monotonic() - t < 6
    assert "Traceback" not in log.read_text()


def test_every_request_has_an_access_log_line(server):
    port, log = server
    for path in ("/health", "/nope"):
        httpx.get(f"http://127.0.0.1:{port}{path}?token=secret", timeout=10)
    time.sleep(0.3)
    lines = [ln for ln in log.read_text().splitlines() if " access " in ln]
    assert any('"GET /health" 200' in ln for ln in lines), lines[-5:]
    assert any('"GET /nope" 404' in ln for ln in lines), lines[-5:]
    assert not any("secret" in ln for ln in lines)  # the query string is never logged


@pytest.fixture(scope="module")
def client():
    from fastapi.testclient import TestClient

    from serving.app import Limits, create_app
    from serving.predictor import Predictor

    app = create_app(Predictor.load(MODEL), Limits(max_samples=1000),
                     cors_origins=["https://lab.example"])  # fmt: skip
    with TestClient(app) as c:
        yield c


def test_foreign_cors_preflight_is_json(client):
    pre = {"Origin": "https://evil.example", "Access-Control-Request-Method": "POST"}
    r = client.options("/predict", headers=pre)
    assert r.status_code == 400 and "CORS" in r.json()["error"]


def test_samples_are_counted_before_the_body_is_parsed(client, monkeypatch):
    import serving.app as app_module

    def parsed(*_a, **_k):
        raise AssertionError("the body was parsed")

    monkeypatch.setattr(app_module.PredictRequest, "model_validate_json", parsed)
    body = b'{"fs_hz": 1000, "samples": [' + b"0," * 5000 + b"0]}"
    r = client.post("/predict", content=body, headers={"content-type": "application/json"})
    assert r.status_code == 413 and "over 1000" in r.json()["error"]
    csv = b"t,accel\n" + b"".join(b"%d,0\n" % i for i in range(5000))
    r = client.post("/predict", files={"file": ("x.csv", csv)})
    assert r.status_code == 413 and "over 1000" in r.json()["error"]
    import io

    import numpy as np

    buf = io.BytesIO()
    np.save(buf, np.zeros(5000, dtype=np.float32))
    monkeypatch.setattr(np, "load", parsed)  # the header decides: the array is never loaded
    r = client.post("/predict", files={"file": ("x.npy", buf.getvalue())}, data={"fs_hz": "1e3"})
    assert r.status_code == 413 and "over 1000" in r.json()["error"]


def test_unknown_form_fields_are_refused_and_the_version_is_the_packages(client):
    csv = (ROOT / "examples" / "recordings" / "impact_beta12.csv").read_bytes()
    r = client.post("/predict", files={"file": ("x.csv", csv)}, data={"fs": "1000"})
    assert r.status_code == 422 and "unknown form field 'fs'" in r.json()["error"]
    assert client.get("/openapi.json").json()["info"]["version"] == __version__
