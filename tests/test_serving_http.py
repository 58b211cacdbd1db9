"""The HTTP predictor: endpoints, JSON errors, limits (413, 429, 503), fuzzing, a live server."""

from __future__ import annotations

import asyncio
import json
import tempfile
import time
import warnings
from pathlib import Path

import httpx
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from live_server import serving

from serving.app import Limits, create_app
from serving.predictor import Predictor
from stiffnet.recordings import read_recording

with warnings.catch_warnings():
    warnings.simplefilter("ignore")
    from fastapi.testclient import TestClient

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples" / "recordings"
EXAMPLE = EXAMPLES / "impact_beta45.csv"


@pytest.fixture(scope="module")
def predictor():
    return Predictor.load()


@pytest.fixture(scope="module")
def client(predictor):
    with TestClient(create_app(predictor, Limits(max_upload_mb=2.0))) as c:
        yield c


@pytest.fixture(scope="module")
def samples():
    return read_recording(EXAMPLE).accel.tolist()


def _is_error(r: httpx.Response, status: int, text: str = "") -> None:
    assert r.status_code == status, (r.status_code, r.text)
    body = r.json()
    assert set(body) == {"error"} and "\n" not in body["error"]
    assert text in body["error"], body


def test_health_model_and_openapi(client, predictor):
    assert client.get("/health").json()["sha256"] == predictor.sha256
    m = client.get("/model").json()
    assert m["name"] == "cnn" and m["limits"]["max_upload_mb"] == 2.0
    schema = client.get("/openapi.json").json()
    body = schema["paths"]["/predict"]["post"]["requestBody"]["content"]
    assert {"application/json", "multipart/form-data"} <= set(body)
    assert "PredictionResult" in schema["components"]["schemas"]


def test_predict_json_and_upload_agree(client, samples):
    r = client.post("/predict", json={"samples": samples, "fs_hz": 1000.0})
    assert r.status_code == 422 and "natural frequency unknown" in r.json()["error"]
    r = client.post("/predict", json={"samples": samples, "fs_hz": 1000.0,
                                      "natural_frequency_hz": 9.48})  # fmt: skip
    assert r.status_code == 200, r.text
    a = r.json()
    assert a["class"] == "hard" and a["natural_frequency_source"] == "request"
    with open(EXAMPLE, "rb") as fh:
        r = client.post(
            "/predict", files={"file": ("run.csv", fh)}, data={"natural_frequency_hz": "9.48"}
        )
    assert r.status_code == 200, r.text
    b = r.json()
    assert b["natural_frequency_source"] == "request" and b["source"] == "run.csv"
    assert b["probabilities"] == pytest.approx(a["probabilities"], abs=1e-9)


def test_errors_are_json_4xx(client, samples):
    _is_error(client.get("/nope"), 404)
    _is_error(client.get("/predict"), 405)
    _is_error(client.post("/predict", content=b"x", headers={"content-type": "text/plain"}), 415)
    _is_error(
        client.post("/predict", content=b"{bad", headers={"content-type": "application/json"}),
        422,
        "invalid JSON",
    )
    _is_error(client.post("/predict", json={"samples": samples}), 422, "fs_hz")
    _is_error(client.post("/predict", json={"samples": samples, "fs_hz": 0}), 422, "fs_hz")
    _is_error(client.post("/predict", json={"samples": [], "fs_hz": 1000}), 422, "empty")
    _is_error(client.post("/predict", json={"samples": [1.0], "fs_hz": 1000}), 422, "one sample")
    _is_error(
        client.post(
            "/predict", json={"samples": samples[:500], "fs_hz": 1000, "natural_frequency_hz": 9.48}
        ),
        422,
        "too short",
    )
    _is_error(
        client.post(
            "/predict", json={"samples": [2.0] * 3000, "fs_hz": 1000, "natural_frequency_hz": 9.48}
        ),
        422,
        "constant",
    )
    _is_error(client.post("/predict", json={"samples": ["a"], "fs_hz": 1000}), 422, "samples")
    nan = '{"samples": [1.0, NaN, 2.0], "fs_hz": 1000}'
    _is_error(
        client.post("/predict", content=nan, headers={"content-type": "application/json"}),
        422,
        "samples.1: Input should be a finite number",
    )
    _is_error(
        client.post("/predict", files={"file": ("r.csv", b"time,acc\n0,1\n")}), 422, "wrong header"
    )
    _is_error(client.post("/predict", files={"file": ("r.xyz", b"1")}), 422, "extension")
    _is_error(client.post("/predict", files={"file": ("r.npy", b"1")}), 422, "sampling rate")
    _is_error(
        client.post("/predict", files={"file": ("r.csv", b"t,accel\n")}, data={"fs_hz": "abc"}),
        422,
        "fs_hz",
    )
    _is_error(
        client.post("/predict", data={"fs_hz": "1"}, files={"other": ("r.csv", b"")}), 400, "file"
    )


def test_a_json_number_written_as_a_lab_writes_it_says_what_to_write(client, samples):
    """A decimal comma or a unit in a JSON number names the value and what to write."""
    r = client.post("/predict", json={"samples": samples, "fs_hz": "1000,0"})
    _is_error(r, 422, "fs_hz: Input should be a valid number, got '1000,0' (a comma in a number")
    r = client.post("/predict", json={"samples": samples, "fs_hz": 1000,
                                      "natural_frequency_hz": "9.48 Hz"})  # fmt: skip
    _is_error(r, 422, "got '9.48 Hz' (the number alone: the name carries the unit)")


def test_a_json_body_says_every_field_it_lacks(client, samples):
    """A body naming its samples ``accel`` was told 'accel: Extra inputs are not permitted
    (+2 more)': not that samples and fs_hz are missing."""
    res = client.post("/predict", json={"accel": samples, "natural_frequency_hz": 9.48})
    _is_error(res, 422, "invalid JSON body: samples: Field required; fs_hz: Field required; "
                        "accel: Extra inputs are not permitted")  # fmt: skip
    assert "more)" not in res.json()["error"]


def test_body_limit_on_header_and_on_stream(client):
    big = b"x" * (3 * 1024 * 1024)
    _is_error(
        client.post("/predict", content=big, headers={"content-type": "application/json"}),
        413,
        "2 MB",
    )

    def chunks():  # no Content-Length: chunked transfer, counted while streaming
        for _ in range(300):
            yield b"y" * 10_000

    _is_error(
        client.post("/predict", content=chunks(), headers={"content-type": "application/json"}), 413
    )
    with_file = client.post("/predict", files={"file": ("r.csv", big)})
    _is_error(with_file, 413)


class _Slow:
    """Stand-in predictor whose predictions take `seconds`."""

    name, sha256, kind = "slow", "0" * 64, "cnn"

    def __init__(self, seconds: float) -> None:
        self.seconds = seconds

    def predict(self, *args, **kwargs):
        time.sleep(self.seconds)
        return {"class": "soft"}

    def info(self):
        return {"name": self.name}


async def _concurrent(app, n: int) -> list[httpx.Response]:
    transport = httpx.ASGITransport(app=app)
    async with httpx.AsyncClient(transport=transport, base_url="http://t") as c:
        body = {"samples": [0.0, 1.0], "fs_hz": 1000.0}
        return await asyncio.gather(*(c.post("/predict", json=body) for _ in range(n)))


def test_saturation_gives_429_and_an_overrun_503_with_retry_after():
    app = create_app(_Slow(0.5), Limits(max_concurrency=1, max_queue=1, timeout_s=5))
    codes = sorted(r.status_code for r in asyncio.run(_concurrent(app, 4)))
    assert codes == [200, 200, 429, 429]
    app = create_app(_Slow(1.0), Limits(max_concurrency=1, timeout_s=0.2))
    (r,) = asyncio.run(_concurrent(app, 1))
    _is_error(r, 503, "did not finish within the 0.2 s timeout")
    assert int(r.headers["retry-after"]) >= 1


def test_a_started_prediction_that_ends_within_its_grace_is_answered():
    """Past the timeout a started prediction holds its worker to its end anyway: one that
    ends within the grace (another timeout) gets its result, not a refusal to run it again."""
    app = create_app(_Slow(0.35), Limits(max_concurrency=1, timeout_s=0.25))
    (r,) = asyncio.run(_concurrent(app, 1))
    assert r.status_code == 200 and r.json() == {"class": "soft"}


def test_a_started_prediction_past_its_timeout_is_answered_up_to_the_ceiling(server_log):
    """A started prediction that ends at 2.5 times the timeout, before the ceiling of 3 times
    it: 200 with its result (its client was waiting; a refusal would make it run again),
    and one log line at the timeout saying what it ran and the ceiling it is given."""
    from serving.app import OVERRUN_GRACE

    assert 1 + OVERRUN_GRACE == 3.0  # the documented ceiling (docs/serving.md)
    app = create_app(_Slow(0.5), Limits(max_concurrency=1, timeout_s=0.2))
    (r,) = asyncio.run(_concurrent(app, 1))
    assert r.status_code == 200 and r.json() == {"class": "soft"}
    lines = [rec.getMessage() for rec in server_log]
    assert any(ln.startswith("overran (given up to the 0.6 s ceiling): this small prediction")
               for ln in lines), lines  # fmt: skip
    assert not any("503" in ln for ln in lines), lines


_floats = st.floats(allow_nan=False, allow_infinity=False, width=32)
_json_bodies = st.one_of(
    st.fixed_dictionaries(
        {
            "samples": st.lists(_floats, max_size=40),
            "fs_hz": st.one_of(st.floats(), st.integers(-5, 10**6), st.text(max_size=3)),
        },
        optional={
            "natural_frequency_hz": st.one_of(st.none(), st.floats()),
            "extra": st.integers(),
        },
    ),
    st.builds(
        lambda n, s, fs: {
            "samples": (np.random.default_rng(s).standard_normal(n)).tolist(),
            "fs_hz": fs,
        },
        st.integers(1000, 5000),
        st.integers(0, 99),
        st.sampled_from([500.0, 1000.0, 3000.0]),
    ),
    st.recursive(
        st.none() | st.booleans() | st.integers() | st.text(max_size=5),
        lambda c: st.lists(c, max_size=3) | st.dictionaries(st.text(max_size=5), c, max_size=3),
        max_leaves=8,
    ),
)


@settings(
    max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(
    body=_json_bodies,
    raw=st.binary(max_size=300),
    name=st.sampled_from(["r.csv", "r.npy", "r.wav", "r.tdms", "r", "../r.csv", "r.CSV"]),
    use_file=st.booleans(),
)
def test_http_never_500(client, body, raw, name, use_file):
    if use_file:
        r = client.post("/predict", files={"file": (name, raw)}, data={"fs_hz": "1000"})
    else:
        r = client.post(
            "/predict", content=json.dumps(body), headers={"content-type": "application/json"}
        )
    assert r.status_code < 500, r.text
    if r.status_code != 200:
        assert set(r.json()) == {"error"}


def test_live_server(samples):
    """`stiffnet serve` as a process: health, a prediction, a 413, then a clean stop."""
    with tempfile.TemporaryFile() as err, serving("--max-upload-mb", "1", stderr=err) as port:
        base = f"http://127.0.0.1:{port}"
        body = {"samples": samples, "fs_hz": 1000.0, "natural_frequency_hz": 9.48}
        r = httpx.post(f"{base}/predict", json=body, timeout=30)
        assert r.status_code == 200 and r.json()["class"] == "hard"
        r = httpx.post(
            f"{base}/predict",
            content=b"z" * 2_000_000,
            headers={"content-type": "application/json"},
            timeout=30,
        )
        assert r.status_code == 413 and "error" in r.json()


def test_upload_with_columns_and_time_unit_fields(client):
    """A lab export (time in ms, other column names) predicts like the t,accel file."""
    rec = read_recording(EXAMPLE)
    lines = [f"{1000 * k / rec.fs_hz:.6g};{float(a)!r},0" for k, a in enumerate(rec.accel)]
    lab = ("Time (ms),Acc (g),T\n" + "\n".join(lines).replace(";", ",")).encode()
    with open(EXAMPLE, "rb") as fh:
        ref = client.post("/predict", files={"file": ("run.csv", fh)},
                          data={"natural_frequency_hz": "9.48"}).json()  # fmt: skip
    fields = {"natural_frequency_hz": "9.48", "columns": "time (ms),acc (g)", "time_unit": "ms"}
    r = client.post("/predict", files={"file": ("lab.csv", lab)}, data=fields)
    assert r.status_code == 200, r.text
    assert r.json()["beta"] == pytest.approx(ref["beta"], rel=1e-9)
    assert r.json()["fs_hz"] == pytest.approx(rec.fs_hz)
    # without the fields the header is refused with the mapping to use
    _is_error(client.post("/predict", files={"file": ("lab.csv", lab)}), 422,
              "form field columns=Time (ms),Acc (g) and time_unit=ms")  # fmt: skip
    _is_error(client.post("/predict", files={"file": ("lab.csv", lab)},
                          data={**fields, "time_unit": "h"}), 422, "unknown time unit")  # fmt: skip
    spec = client.get("/openapi.json").json()["paths"]["/predict"]["post"]["requestBody"]
    props = spec["content"]["multipart/form-data"]["schema"]["properties"]
    assert props["time_unit"]["enum"] == ["s", "ms", "us"] and "columns" in props


def test_every_route_has_a_typed_response_and_lists_its_errors(client):
    from serving.schemas import HealthResponse, ModelResponse

    schema = client.get("/openapi.json").json()
    comps = schema["components"]["schemas"]
    expected = {
        ("/predict", "post"): ("PredictionResult", {"400", "413", "415", "422", "429", "503"}),
        ("/health", "get"): ("HealthResponse", {"405", "413"}),
        ("/model", "get"): ("ModelResponse", {"405", "413"}),
        ("/log", "post"): ("LogResult", {"400", "413", "415", "422", "429", "503"}),
    }
    for (path, method), (model, errors) in expected.items():
        responses = schema["paths"][path][method]["responses"]
        ok = responses["200"]["content"]["application/json"]["schema"]
        assert ok == {"$ref": f"#/components/schemas/{model}"}, path
        assert comps[model]["properties"], model  # a typed object, not {}
        assert errors <= set(responses), (path, set(responses))
        for code in set(responses) - {"200"}:
            ref = responses[code]["content"]["application/json"]["schema"]["$ref"]
            assert ref.endswith("/ErrorBody"), (path, code)
    assert comps["HealthResponse"]["properties"]["in_flight"]["type"] == "integer"
    assert "limits" in comps["ModelResponse"]["properties"]
    # the answers validate against their models
    HealthResponse.model_validate(client.get("/health").json())
    m = ModelResponse.model_validate(client.get("/model").json())
    assert m.limits.max_upload_mb == 2.0 and m.class_names
    _is_error(client.delete("/health"), 405)


def test_log_route_and_channel_field(client, tmp_path):
    """POST /log gives the stiffness log; a two-channel upload needs its channel field."""
    from scipy.io import wavfile

    from serving.schemas import LogResult

    rec = read_recording(EXAMPLES / "impact_beta12.csv")
    hard = read_recording(EXAMPLE)
    x = np.concatenate([rec.accel, hard.accel])
    body = {"samples": x.tolist(), "fs_hz": rec.fs_hz, "natural_frequency_hz": 9.48}
    r = client.post("/log", json=body)
    assert r.status_code == 200, r.text
    doc = LogResult.model_validate(r.json())
    assert [la.class_ for la in doc.layers] == ["soft", "hard"]
    assert abs(doc.changes[0].t_s - rec.duration_s) <= 1.0
    _is_error(client.post("/log", json={**body, "natural_frequency_hz": None}), 422,
              "natural frequency unknown")  # fmt: skip
    # a data sheet is divided out of every window and said so; a bad one is a 4xx line
    sheet = {"lowpass_hz": 300.0, "lowpass_order": 2.0}
    r = client.post("/log", json={**body, "sensor": sheet})
    assert r.status_code == 200, r.text
    assert r.json()["chain_undone"]["source"] == "data sheet"
    assert r.json()["chain_undone"]["lowpass_hz"] == 300.0
    _is_error(client.post("/log", json={**body, "sensor": {"gain": 2.0}}), 422,
              "unknown sensor key(s) gain")  # fmt: skip
    two = np.stack([np.zeros(hard.accel.size), hard.accel], axis=1).astype(np.float32)
    wavfile.write(tmp_path / "daq.wav", int(hard.fs_hz), two)
    raw = (tmp_path / "daq.wav").read_bytes()
    fields = {"natural_frequency_hz": "9.48"}
    _is_error(client.post("/predict", files={"file": ("daq.wav", raw)}, data=fields), 422,
              "2 channels (0..1); choose one")  # fmt: skip
    r = client.post("/predict", files={"file": ("daq.wav", raw)}, data={**fields, "channel": "1"})
    assert r.status_code == 200, r.text
    assert r.json()["class"] == "hard"


def test_an_upload_over_the_limit_is_refused_before_it_queues(tmp_path):
    """The size an .npy header or a CSV's lines say is checked as soon as it is spooled."""
    from serving.app import TooManySamples, check_upload_size

    path = tmp_path / "upload.npy"
    np.save(path, np.zeros(101, dtype=np.float32))
    check_upload_size(path, 101)
    with pytest.raises(TooManySamples, match="over 100 samples"):
        check_upload_size(path, 100)


def test_a_job_that_fails_after_its_503_logs_one_line(server_log):
    """Its exception has no request to go to: one warning, no 'exception never retrieved'."""
    from concurrent.futures import Future

    from serving.app import _outcome_unheard

    fut: Future = Future()
    fut.set_exception(ValueError("late\nfailure"))
    _outcome_unheard(fut)
    (line,) = [r.getMessage() for r in server_log]
    assert line.startswith("a request answered 503 failed afterwards: late") and "\n" not in line


def test_lane_cost_schedules_its_backlog_and_prices_at_what_it_measured():
    """Expected wait by list scheduling of the estimates; the price per sample is the
    highest of the mean (the seed until a measurement), the latest measurement and what a
    running job has spent already."""
    from serving.load_shedding import COST_EWMA, OVERRUN_LEFT, LaneCost

    lane = LaneCost(workers=2, seed=1e-3)
    assert lane.expected_start_s(0.0) == 0.0  # idle: a worker is free now
    a = lane.submitted(5000)  # 5 s at the seed
    lane.started(a, 100.0)
    assert lane.expected_start_s(101.0) == 0.0  # one worker still free
    b = lane.submitted(3000)  # 3 s, takes the second worker
    lane.started(b, 101.0)
    lane.submitted(2000)  # queued: the first free worker (b's, at t = 104) takes it
    assert lane.expected_start_s(102.0) == pytest.approx(3.0)  # a's worker frees at 105
    # at t = 110 b has spent 9 s on 3000 samples: 3 ms a sample at least, for every job:
    # a 15 s (5 left), b 9 s (overran: OVERRUN_LEFT of it left), the queued one 6 s after b
    assert lane.s_per_sample_now(110.0) == pytest.approx(3e-3)
    assert lane.expected_start_s(110.0) == pytest.approx(min(5.0, OVERRUN_LEFT * 9.0 + 6.0))
    assert lane.expected_s(1000, 110.0) == pytest.approx(3.0)
    lane.ended(a)
    lane.ended(b)
    assert lane.expected_start_s(110.0) == 0.0  # the queued one runs, a worker is free
    lane.measure(1000, 2.0)
    assert (lane.s_per_sample, lane.measured) == (2e-3, 1)  # the seed is replaced
    lane.measure(1000, 4.0)
    assert lane.s_per_sample == pytest.approx((1 - COST_EWMA) * 2e-3 + COST_EWMA * 4e-3)
    assert lane.s_per_sample_now(200.0) == pytest.approx(4e-3)  # the latest, higher
    lane.measure(1000, 1.0)
    assert lane.s_per_sample_now(200.0) == pytest.approx(lane.s_per_sample)  # the mean, higher
    lane.measure(0, 1.0)  # nothing to learn from
    assert lane.measured == 3


class _Held:
    """Stand-in predictor: the first prediction lasts `first_s`; later ones wait for
    `release`. Records the samples of every prediction it started."""

    name, sha256, kind = "held", "0" * 64, "cnn"

    def __init__(self, first_s: float) -> None:
        import threading

        self.first_s, self.seen = first_s, []
        self.entered, self.release = threading.Event(), threading.Event()

    def predict(self, accel, *args, **kwargs):
        self.seen.append(len(accel))
        if len(self.seen) == 1:
            time.sleep(self.first_s)
        else:
            self.entered.set()
            assert self.release.wait(20)
        return {"class": "soft"}

    def info(self):
        return {"name": self.name}


def test_a_job_that_would_pass_the_timeout_is_shed_before_any_work():
    """With a measured cost of >= 2 ms a sample, a queued 20,000-sample job (>= 40 s) cannot
    finish within 16 s of the 20 s timeout: 429 with Retry-After and the reason, never started; a
    100-sample job queued behind the same work fits and is served. Deterministic: sleeps
    only bound the cost from below, and a slower machine measures more, not less."""
    held = _Held(first_s=0.2)
    app = create_app(held, Limits(max_concurrency=1, max_queue=8, timeout_s=20))
    lane = app.state.admission.cost["small"]

    def body(n: int) -> dict:
        return {"samples": [0.5] * n, "fs_hz": 1000.0}

    async def scenario() -> tuple:
        transport = httpx.ASGITransport(app=app)
        async with httpx.AsyncClient(transport=transport, base_url="http://t") as c:
            first = await c.post("/predict", json=body(100))  # measures the lane's cost
            assert lane.measured == 1 and lane.s_per_sample >= 0.2 / 101
            running = asyncio.ensure_future(c.post("/predict", json=body(100)))
            assert await asyncio.to_thread(held.entered.wait, 10)  # it holds the one worker
            queued = asyncio.ensure_future(c.post("/predict", json=body(100)))
            for _ in range(500):  # until it waits in the lane
                if len(lane.jobs) == 2:
                    break
                await asyncio.sleep(0.01)
            shed = await c.post("/predict", json=body(20_000))
            held.release.set()
            return first, await running, await queued, shed

    first, running, queued, shed = asyncio.run(scenario())
    assert [first.status_code, running.status_code, queued.status_code] == [200, 200, 200]
    _is_error(shed, 429, "would not finish within the 20 s timeout")
    assert "(20001 samples)" in shed.json()["error"] and "(from 1 measured)" in shed.json()["error"]
    assert int(shed.headers["retry-after"]) >= 1
    assert 20_000 not in held.seen and held.seen == [100, 100, 100]  # never started
    assert not lane.jobs  # everything ended


def test_a_large_upload_that_would_pass_the_timeout_is_shed_and_its_file_removed(
    tmp_path, monkeypatch
):
    """The large lane: a cost of 10 ms a sample (as measured), a 2,000-sample .npy running
    (20 s expected) and another queued behind it (20 s more) cannot finish within 24 s of
    the 30 s timeout: 429 with the seconds until it would fit, its spooled file gone."""
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))  # where uploads are spooled
    held = _Held(first_s=0.0)
    held.seen.append(0)  # every prediction waits for `release`
    app = create_app(held, Limits(small_upload_mb=0.001, timeout_s=30))  # 1 kB: all large
    lane = app.state.admission.cost["large"]
    lane.measure(1000, 10.0)
    buf = __import__("io").BytesIO()
    np.save(buf, np.full(2000, 0.5))
    form = {"fs_hz": "1000", "natural_frequency_hz": "9.48"}

    async def scenario() -> tuple:
        transport = httpx.ASGITransport(app=app)
        async with httpx.AsyncClient(transport=transport, base_url="http://t") as c:
            files = {"file": ("run.npy", buf.getvalue())}
            running = asyncio.ensure_future(c.post("/predict", files=files, data=form))
            assert await asyncio.to_thread(held.entered.wait, 10)
            spooled = sorted(p.name for p in tmp_path.iterdir())
            shed = await c.post("/predict", files=files, data=form)
            after_shed = sorted(p.name for p in tmp_path.iterdir())
            held.release.set()
            return await running, shed, spooled, after_shed

    running, shed, spooled, after_shed = asyncio.run(scenario())
    assert running.status_code == 200, running.text
    _is_error(shed, 429, "(2000 samples) about 20.0 s at 1e+04 us per sample (from 1 measured)")
    assert 1 <= int(shed.headers["retry-after"]) <= 16  # 20 + 20 - 24 s, less what has run
    assert len(spooled) == 1 and after_shed == spooled  # only the running job's upload
    assert held.seen == [0, 2000] and not list(tmp_path.iterdir()) and not lane.jobs


def test_a_job_too_slow_alone_at_the_lanes_load_is_shed_until_its_measure_is_stale():
    """On a free worker a job is priced at its CPU cost times the lane's slow-down: 1 ms of
    CPU a sample at 10 times its CPU time makes 2,000 samples 20 s, over 16 s of the 20 s
    timeout (429, Retry-After the timeout, never started), 500 samples 5 s (served). With
    no slow-down measured in the last minute the job is started: it measures the lane again
    (a lane refused for a load that has fallen opens again)."""
    held = _Held(first_s=0.0)
    held.release.set()
    app = create_app(held, Limits(max_concurrency=1, timeout_s=20))
    lane = app.state.admission.cost["small"]
    lane.measure(1000, 10.0, cpu_s=1.0)
    assert lane.cpu_s_per_sample == 1e-3 and lane.contention.factor(time.monotonic()) == 10
    assert app.state.admission.cost["large"].contention.factor(time.monotonic()) is None

    def body(n: int) -> dict:
        return {"samples": [0.5] * (n - 1), "fs_hz": 1000.0}  # n - 1 numbers, n - 1 commas

    with TestClient(app) as c:
        shed = c.post("/predict", json=body(2000))
        served = c.post("/predict", json=body(500))
        lane.contention.at -= 61.0  # measured over a minute ago
        reopened = c.post("/predict", json=body(2000))
    _is_error(shed, 429, "(2000 samples) needs about 2.0 s of CPU, about 20.0 s at this lane's")
    assert shed.headers["retry-after"] == "20"
    assert (served.status_code, reopened.status_code) == (200, 200)
    assert held.seen == [499, 1999]


def test_too_many_samples_is_413_before_any_load_shedding():
    """A JSON body over max_samples is refused for its size (413, permanent), not for the
    server's load (429, retried), though its cost would also be shed."""
    app = create_app(_Held(0.0), Limits(max_samples=1000, timeout_s=10))
    app.state.admission.cost["small"].measure(1000, 10.0, cpu_s=1.0)  # 1,500 samples: 15 s
    with TestClient(app) as c:
        r = c.post("/predict", json={"samples": [0.5] * 1500, "fs_hz": 1000.0})
    _is_error(r, 413, "over 1000 samples")


def test_a_large_job_with_no_recent_measure_is_priced_at_the_machines_load(monkeypatch):
    """A large job on a free worker, its lane unmeasured lately: priced at the machine's load,
    ``(load + 1) / cores``, never at the small lane's slow-down (10 times its CPU time here,
    an upload does not wait on the interpreter lock as small requests do). 4,000 samples at
    1 ms of CPU: at load 1 on 2 cores 4 s (served), at load 19 40 s (429)."""
    import serving.load_shedding as shedding

    monkeypatch.setattr(shedding.os, "sched_getaffinity", lambda _pid: {0, 1})
    app = create_app(_Held(0.0), Limits(small_upload_mb=0.005, timeout_s=20))  # 5 kB: large
    cost = app.state.admission.cost
    cost["small"].measure(1000, 10.0, cpu_s=1.0)
    cost["large"].cpu_s_per_sample = 1e-3
    body = {"samples": [0.5] * 4000, "fs_hz": 1000.0}
    with TestClient(app) as c:
        monkeypatch.setattr(shedding.os, "getloadavg", lambda: (1.0, 1.0, 1.0))
        served = c.post("/predict", json=body)
        cost["large"].contention.at -= 61.0  # its own measure, from the served one, is stale
        monkeypatch.setattr(shedding.os, "getloadavg", lambda: (19.0, 1.0, 1.0))
        shed = c.post("/predict", json=body)
    assert served.status_code == 200, served.text
    _is_error(shed, 429, "about 40.0 s at the machine's load slow-down now (10.0 times")


def test_machine_slow_down_is_the_load_per_core_this_thread_added(monkeypatch):
    import serving.load_shedding as shedding

    monkeypatch.setattr(shedding.os, "getloadavg", lambda: (6.5, 0.0, 0.0))
    assert shedding.machine_slow_down(cores=2) == pytest.approx(3.75)
    assert shedding.machine_slow_down(cores=16) == 1.0  # idle cores: no slow-down


def test_a_running_jobs_progress_is_the_lanes_slow_down_before_it_ends():
    """What slows a running job now is read from its thread's CPU clock: a job that spent
    ~0.1 s of CPU in ~0.4 s of wall time runs ~4 times its CPU time, and the lane (no job
    finished) reads that slow-down while it runs, nothing once it ended."""
    import threading

    from serving.load_shedding import LaneCost

    lane = LaneCost(1, 1e-4)
    spun, go_on = threading.Event(), threading.Event()
    ticket = lane.submitted(1000)
    assert lane.slow_down(time.monotonic()) is None and lane.progress(ticket, 0.0) is None
    worker = threading.Thread(target=_spin_then_sleep, args=(lane, ticket, spun, go_on))
    worker.start()
    assert spun.wait(10)
    wall, cpu = lane.progress(ticket, time.monotonic())
    assert cpu == pytest.approx(0.1, abs=0.05) and wall >= 0.4
    assert lane.slow_down(time.monotonic()) == pytest.approx(wall / cpu, rel=0.05)
    lane.live = False  # a lane of short jobs (the server's small lane) reads finished ones only
    assert lane.slow_down(time.monotonic()) is None
    lane.live = True
    go_on.set()
    worker.join()
    lane.ended(ticket)
    assert lane.slow_down(time.monotonic()) is None


def _spin_then_sleep(lane, ticket, spun, go_on) -> None:
    from serving.load_shedding import thread_cpu_clock

    lane.started(ticket, time.monotonic(), *thread_cpu_clock())
    cpu0 = time.thread_time()
    while time.thread_time() < cpu0 + 0.1:
        pass
    time.sleep(0.3)
    spun.set()
    go_on.wait(10)
