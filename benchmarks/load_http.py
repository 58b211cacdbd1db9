"""Bounded HTTP load test of ``stiffnet serve`` on loopback.

Starts ``stiffnet serve`` as a subprocess on 127.0.0.1 with a free port, waits for
``GET /health``, then ``--clients`` concurrent clients (httpx, asyncio) send
``--requests`` ``POST /predict`` requests in all, each the first ``--seconds``
of the shipped example recording as JSON samples. Reports latency percentiles
(p50, p90, p99, max), throughput, the status codes (5xx must be 0), and the
server's resident memory at start (after one warm-up request), at the middle
and at the end; then stops the server. Exit code 1 if any 5xx or transport error.

    python benchmarks/load_http.py            # 50 clients, 5,000 requests
    python benchmarks/load_http.py --quick    # 20 clients, 300 requests
    python benchmarks/load_http.py --abuse    # small requests alone, then under abuse

``--abuse`` measures the same small requests three times: alone, while
``--uploaders`` clients upload big files (nothing else), and while the server is
abused by big uploads (``--uploaders`` clients each sending ``--uploads``
multipart ``.npy`` files of 2,000,000 float64 samples (16 MB, at the
``--max-samples`` limit; ``--upload-samples``) or 5,000,000 float32 samples (20 MB, over it) at
fs = 50 kHz), stalled bodies (``--stalled`` connections from one other client
address, 127.0.0.2, that send half a body and then nothing), stalled large uploads
(``--stalled-large`` from 127.0.0.3), connections trickling header lines
(``--trickle``, one line every 0.5 s), a 20 MB JSON of zeros (``--zeros``) and
disconnects (``--disconnects`` connections that send half a body and close).
Everything is bounded in count and time (``--deadline``) and sent to loopback
addresses only. Reports the status codes of each kind (5xx must be 0), p50/p99 of
the small requests in each phase, the server's peak RSS (``VmHWM``), its log (one
line per disconnect, no traceback) and the machine's load (``uptime``) at the start
and the end.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import socket
import statistics
import subprocess
import sys
import time
from collections import Counter
from pathlib import Path

import httpx
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "recordings" / "impact_beta45.csv"
#: The example's natural frequency (its sidecar's): the predictor never assumes one, and a
#: request without it is refused (422) before any work, which would measure nothing.
FN_HZ = "9.48"


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def rss_mb(pid: int) -> float:
    """Resident set size of a process in MB (psutil if installed, else /proc)."""
    try:
        import psutil

        return psutil.Process(pid).memory_info().rss / 2**20
    except ImportError:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024
    return float("nan")


def stop(proc: subprocess.Popen) -> None:
    """Terminate the server (kill it after 15 s)."""
    proc.terminate()
    try:
        proc.wait(timeout=15)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()


def wait_healthy(base: str, proc: subprocess.Popen, timeout: float = 60.0) -> None:
    t_end = time.monotonic() + timeout
    while time.monotonic() < t_end:
        if proc.poll() is not None:
            raise SystemExit(f"server exited with code {proc.returncode}")
        try:
            if httpx.get(f"{base}/health", timeout=1.0).status_code == 200:
                return
        except httpx.HTTPError:
            time.sleep(0.2)
    raise SystemExit("server did not become healthy")


async def run_load(base: str, body: bytes, n_requests: int, n_clients: int, pid: int) -> dict:
    latencies: list[float] = []
    codes: Counter = Counter()
    rss: dict[str, float] = {}
    issued = 0

    async def client(c: httpx.AsyncClient) -> None:
        nonlocal issued
        while issued < n_requests:
            issued += 1
            if issued == n_requests // 2:
                rss["middle"] = rss_mb(pid)
            t = time.perf_counter()
            try:
                r = await c.post(
                    "/predict", content=body, headers={"content-type": "application/json"}
                )
                codes[r.status_code] += 1
            except httpx.HTTPError as exc:
                codes[f"transport error {type(exc).__name__}"] += 1
            latencies.append(time.perf_counter() - t)

    limits = httpx.Limits(max_connections=n_clients, max_keepalive_connections=n_clients)
    async with httpx.AsyncClient(base_url=base, timeout=120.0, limits=limits) as c:
        t0 = time.perf_counter()
        await asyncio.gather(*(client(c) for _ in range(n_clients)))
        wall = time.perf_counter() - t0
    return {"latencies": latencies, "codes": codes, "wall_s": wall, "rss": rss}


def peak_rss_mb(pid: int) -> float:
    """Peak resident set size of a process (VmHWM) in MB."""
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) / 1024
    return float("nan")


def _code(r: httpx.Response) -> int | str:
    """The status, or "429 shed" for a load-shedding refusal (a job that would not finish
    in time, refused before any work; "at start" when its worker refused it) apart from a
    full lane's 429."""
    if r.status_code == 429 and "would not finish within" in r.text:
        when = " at start" if "refused before any work" in r.text else ""
        return f"429 shed{when} (Retry-After {r.headers.get('retry-after', '?')} s)"
    if r.status_code == 429 and "found no free worker" in r.text:
        return "429 no worker in time"
    return r.status_code


async def small_requests(base: str, body: bytes, n: int, clients: int) -> tuple[list, Counter]:
    """``n`` small JSON predictions from ``clients`` concurrent clients: latencies, codes."""
    latencies: list[float] = []
    codes: Counter = Counter()
    left = n

    async def one(c: httpx.AsyncClient) -> None:
        nonlocal left
        while left > 0:
            left -= 1
            t = time.perf_counter()
            try:
                r = await c.post("/predict", content=body,
                                 headers={"content-type": "application/json"})  # fmt: skip
                codes[_code(r)] += 1
            except httpx.HTTPError as exc:
                codes[f"transport error {type(exc).__name__}"] += 1
            latencies.append(time.perf_counter() - t)

    async with httpx.AsyncClient(base_url=base, timeout=120.0) as c:
        await asyncio.gather(*(one(c) for _ in range(clients)))
    return latencies, codes


async def big_uploads(
    base: str, files: list[bytes], per_client: int, body_timeout_s: float = 20.0
) -> Counter:
    """Each file's client uploads it ``per_client`` times (waiting Retry-After on 429).

    A 408 (its body not received within ``body_timeout_s``) and a transport error are
    counted apart as "client:" when this client took longer than ``body_timeout_s`` on the
    request: on a loaded machine the benchmark's own process may not send 16 MB in time,
    which says nothing of the server's answers.
    """
    codes: Counter = Counter({"200 s": [], "5xx s": []})  # type: ignore[dict-item]

    async def one(data: bytes) -> None:
        async with httpx.AsyncClient(base_url=base, timeout=120.0) as c:
            for _ in range(per_client):
                try:
                    form = {"fs_hz": "50000", "natural_frequency_hz": FN_HZ}
                    t = time.perf_counter()
                    r = await c.post("/predict", files={"file": ("big.npy", data)}, data=form)
                    slow = time.perf_counter() - t > body_timeout_s
                    codes[f"client: 408 after {body_timeout_s:g} s" if r.status_code == 408
                          and slow else _code(r)] += 1  # fmt: skip
                    if r.status_code == 200 or r.status_code >= 500:  # how long they took
                        key = "200 s" if r.status_code == 200 else "5xx s"
                        codes[key] += [round(time.perf_counter() - t, 1)]
                    if r.status_code in (429, 503):
                        await asyncio.sleep(float(r.headers.get("retry-after", "1")))
                except httpx.HTTPError as exc:
                    slow = time.perf_counter() - t > body_timeout_s
                    codes[f"{'client: ' if slow else ''}transport error "
                          f"{type(exc).__name__}"] += 1  # fmt: skip

    await asyncio.gather(*(one(f) for f in files))
    return codes


async def half_bodies(
    port: int, n: int, close: bool, wait_s: float, source: str = "127.0.0.1", large: bool = False
) -> Counter:
    """``n`` connections from ``source`` sending headers and half a body; then close, or wait.

    ``large``: a 5 MB multipart upload's head (the large lane) instead of a small JSON.
    """
    kind, length = ((b"multipart/form-data; boundary=x", 5_000_000) if large
                    else (b"application/json", 200_000))  # fmt: skip
    head = (b"POST /predict HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: " + kind
            + b"\r\nContent-Length: %d\r\n\r\n" % length)  # fmt: skip
    codes: Counter = Counter()

    async def one(i: int) -> None:
        await asyncio.sleep(0.02 * i)  # spread over the abuse phase
        try:
            reader, writer = await asyncio.open_connection("127.0.0.1", port,
                                                           local_addr=(source, 0))  # fmt: skip
        except OSError as exc:
            codes[f"connect error {type(exc).__name__}"] += 1
            return
        part = (b'--x\r\nContent-Disposition: form-data; name="file"; filename="a.npy"\r\n\r\n'
                + b"\x00" * 4000 if large else b'{"samples": [0.5, 1.5, ' * 200)  # fmt: skip
        writer.write(head + part)
        await writer.drain()
        if close:
            writer.close()
            codes["closed mid-body"] += 1
            return
        try:
            line = await asyncio.wait_for(reader.readline(), wait_s)
            codes[int(line.split()[1]) if line else "closed without answer"] += 1
        except TimeoutError:
            codes["no answer in time"] += 1
        finally:
            writer.close()

    await asyncio.gather(*(one(i) for i in range(n)))
    return codes


async def trickle_heads(port: int, n: int, seconds: float) -> Counter:
    """``n`` connections sending one header line every 0.5 s for ``seconds``, never ending."""
    codes: Counter = Counter()

    async def one(i: int) -> None:
        try:
            reader, writer = await asyncio.open_connection("127.0.0.1", port,
                                                           local_addr=("127.0.0.4", 0))  # fmt: skip
        except OSError as exc:
            codes[f"connect error {type(exc).__name__}"] += 1
            return
        t0 = time.perf_counter()
        answer = asyncio.ensure_future(reader.readline())
        try:
            writer.write(b"POST /predict HTTP/1.1\r\nHost: 127.0.0.1\r\n")
            while time.perf_counter() - t0 < seconds and not answer.done():
                await asyncio.sleep(0.5)
                writer.write(b"X-Trickle: %d\r\n" % i)
                await writer.drain()
        except OSError:
            pass  # closed by the server
        try:
            line = await asyncio.wait_for(answer, 1.0)
            waited = 5 * round((time.perf_counter() - t0) / 5)
            codes[f"{int(line.split()[1])} after ~{waited} s" if line else "closed"] += 1
        except (OSError, TimeoutError):
            codes["still open at the end"] += 1
        finally:
            writer.close()

    await asyncio.gather(*(one(i) for i in range(n)))
    return codes


async def zeros_json(port: int, megabytes: float) -> Counter:
    """One JSON body of ``megabytes`` of zeros (``"0,"`` repeated): 413 before parsing.

    Sent on a raw connection that waits 2 s for an answer to its head before sending the
    body (as ``Expect: 100-continue`` would): the server answers 413 from the
    Content-Length and closes, and a client still sending 20 MB then sees only a reset
    ("transport error ReadError"), the answer unread.
    """
    body = b'{"fs_hz": 1000, "samples": [' + b"0," * int(megabytes * 5e5) + b"0]}"
    head = (b"POST /predict HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: application/json"
            b"\r\nContent-Length: %d\r\n\r\n" % len(body))  # fmt: skip
    try:
        reader, writer = await asyncio.open_connection("127.0.0.1", port)
    except OSError as exc:
        return Counter([f"connect error {type(exc).__name__}"])
    try:
        writer.write(head)
        await writer.drain()
        try:
            line = await asyncio.wait_for(reader.readline(), 2.0)
        except TimeoutError:  # no answer to the head: send the body
            writer.write(body)
            await writer.drain()
            line = await asyncio.wait_for(reader.readline(), 120.0)
        return Counter([int(line.split()[1]) if line else "closed without answer"])
    except (OSError, TimeoutError) as exc:
        return Counter([f"transport error {type(exc).__name__}"])
    finally:
        writer.close()


def burners(n: int) -> list[subprocess.Popen]:
    """``n`` processes spinning a core each (``--burn``): a loaded machine on demand."""
    return [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(n)]


def load_average() -> str:
    return " ".join(Path("/proc/loadavg").read_text().split()[:3])


def percentiles(lat: list[float]) -> str:
    a = np.array(lat) * 1e3
    return (f"p50 {np.percentile(a, 50):.0f} ms, p99 {np.percentile(a, 99):.0f} ms, "
            f"max {a.max():.0f} ms (n={a.size})")  # fmt: skip


def run_abuse(args: argparse.Namespace, body: bytes) -> int:
    """Small requests alone, then under big uploads, stalled bodies and disconnects."""
    import tempfile

    port = free_port()
    base = f"http://127.0.0.1:{port}"
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    cmd = [sys.executable, "-m", "stiffnet", "serve", "--port", str(port)]
    if not args.legacy_server:
        cmd += ["--body-timeout-s", str(args.body_timeout_s)]
    rng = np.random.default_rng(0)
    npy = []
    for i in range(args.uploaders):  # half at the samples limit, half over it
        arr = (rng.standard_normal(args.upload_samples) if i % 2 == 0
               else rng.standard_normal(5_000_000).astype(np.float32))  # fmt: skip
        buf = __import__("io").BytesIO()
        np.save(buf, arr)
        npy.append(buf.getvalue())
    log = tempfile.NamedTemporaryFile(prefix="stiffnet-serve-", suffix=".log", delete=False)
    out = tempfile.NamedTemporaryFile(prefix="stiffnet-serve-", suffix=".out", delete=False)
    burning = burners(args.burn)
    proc = subprocess.Popen(cmd, env=env, stdout=out, stderr=log)
    try:
        if burning:  # the load average follows in about a minute
            time.sleep(args.burn_lead_s)
        wait_healthy(base, proc, timeout=120.0)
        for _ in range(3):  # warm-up
            httpx.post(f"{base}/predict", content=body, timeout=60,
                       headers={"content-type": "application/json"})  # fmt: skip
        rss_start = rss_mb(proc.pid)
        load_start = load_average()
        alone, codes_alone = asyncio.run(small_requests(base, body, args.small, args.small_clients))

        async def uploads_only() -> tuple:
            return await asyncio.wait_for(asyncio.gather(
                small_requests(base, body, args.small, args.small_clients),
                big_uploads(base, npy, args.uploads, args.body_timeout_s)),
                args.deadline)  # fmt: skip

        (uploading, codes_up), codes_big_only = asyncio.run(uploads_only())

        async def abuse() -> tuple:
            wait = args.body_timeout_s + 30
            return await asyncio.wait_for(asyncio.gather(
                small_requests(base, body, args.small, args.small_clients),
                big_uploads(base, npy, args.uploads, args.body_timeout_s),
                half_bodies(port, args.stalled, close=False, wait_s=wait, source="127.0.0.2"),
                half_bodies(port, args.stalled_large, close=False, wait_s=wait,
                            source="127.0.0.3", large=True),
                trickle_heads(port, args.trickle, args.trickle_s),
                zeros_json(port, 20.0) if args.zeros else asyncio.sleep(0, Counter()),
                half_bodies(port, args.disconnects, close=True, wait_s=0, source="127.0.0.5"),
            ), args.deadline)  # fmt: skip

        t0 = time.perf_counter()
        ((under, codes_small), codes_big, codes_stall, codes_stall_large, codes_trickle,
         codes_zeros, codes_gone) = asyncio.run(abuse())  # fmt: skip
        wall = time.perf_counter() - t0
        time.sleep(1.0)
        health = httpx.get(f"{base}/health", timeout=5).status_code
        peak = peak_rss_mb(proc.pid)
    finally:
        stop(proc)
        for b in burning:
            stop(b)
        log.close()
        out.close()
    text = Path(log.name).read_text(errors="replace")
    started = [ln for ln in (Path(out.name).read_text(errors="replace") + text).splitlines()
               if ln.startswith("warm-up")]  # fmt: skip
    Path(log.name).unlink()
    Path(out.name).unlink()
    all_codes = [codes_alone, codes_up, codes_big_only, codes_small, codes_big, codes_stall,
                 codes_stall_large, codes_zeros]  # fmt: skip
    n5xx = sum(v for c in all_codes for k, v in c.items() if isinstance(k, int) and k >= 500)
    opts = (
        "defaults" if args.legacy_server else f"defaults, --body-timeout-s {args.body_timeout_s:g}"
    )
    print(f"server: stiffnet serve ({opts}); small request = {len(body) / 1e3:.0f} kB JSON, "
          f"{args.small_clients} clients")  # fmt: skip
    print(f"load average (uptime) at start: {load_start}; at the end: {load_average()}"
          + (f" ({args.burn} CPU burners)" if args.burn else ""))  # fmt: skip
    print(f"server start: {started[0] if started else 'no warm-up line'}")
    print(f"small requests alone:       {percentiles(alone)}; codes {dict(codes_alone)}")
    print(f"small requests, {args.uploaders} uploaders: {percentiles(uploading)}; codes "
          f"{dict(codes_up)}; uploads {dict(sorted(codes_big_only.items(), key=str))}")  # fmt: skip
    print(f"small requests under abuse: {percentiles(under)}; codes {dict(codes_small)}")
    print(f"big uploads ({args.uploaders} clients x {args.uploads}, .npy of "
          f"{args.upload_samples:,} and 5 M samples): "
          f"codes {dict(sorted(codes_big.items(), key=str))}")  # fmt: skip
    print(f"stalled bodies ({args.stalled}, one client): {dict(codes_stall)}")
    print(f"stalled large uploads ({args.stalled_large}, one client): {dict(codes_stall_large)}")
    print(f"trickled heads ({args.trickle}, {args.trickle_s:g} s): {dict(codes_trickle)}")
    print(f"20 MB JSON of zeros: {dict(codes_zeros)}")
    print(f"disconnects ({args.disconnects}): {dict(codes_gone)}")
    lines = text.splitlines()
    n_gone = sum("disconnected before its request body" in ln for ln in lines)
    shed = [ln for ln in lines if "(load shed)" in ln]
    print(f"server log: {len(shed)} load-shedding lines" + "".join(
        f"\n  {ln.split('(load shed): ', 1)[1][:260]}" for ln in shed[:4]))  # fmt: skip
    overrun = [ln.split("503 (overrun): ", 1)[1] for ln in lines if "503 (overrun)" in ln]
    print(f"server log: {len(overrun)} overrun (503) lines" + "".join(
        f"\n  {ln[:260]}" for ln in overrun[:4]))  # fmt: skip
    late = [ln.split("overran ", 1)[1] for ln in lines if "overran (given up" in ln]
    print(f"server log: {len(late)} started predictions past the timeout" + "".join(
        f"\n  {ln[:260]}" for ln in late[:4]))  # fmt: skip
    print(f"abuse phase wall {wall:.1f} s; /health after: {health}")
    print(f"server RSS MB: start {rss_start:.0f}, peak (VmHWM) {peak:.0f}")
    print(f"server log: {len(lines)} lines, {n_gone} disconnect lines, "
          f"{text.count('Traceback')} tracebacks")  # fmt: skip
    if "Traceback" in text:  # the first one, so that a run says what broke
        first = text[text.index("Traceback") :].splitlines()
        end = next((i for i, ln in enumerate(first[1:], 1) if not ln.startswith(" ")), 0)
        print("first traceback:\n" + "\n".join(first[: end + 1]))
    print(f"5xx: {n5xx}")
    if not codes_alone.get(200):  # refusals answer fast and cost nothing: nothing measured
        print("no small request was answered 200: the latencies measure refusals")
        return 1
    return 1 if n5xx or "Traceback" in text or health != 200 else 0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="20 clients, 300 requests")
    ap.add_argument("--requests", type=int, default=5000)
    ap.add_argument("--clients", type=int, default=50)
    ap.add_argument("--seconds", type=float, default=5.0, help="recording length per request")
    ap.add_argument("--max-concurrency", type=int, default=2, help="server worker threads")
    ab = ap.add_argument_group("--abuse")
    ab.add_argument("--abuse", action="store_true", help="small requests under abuse")
    ab.add_argument("--small", type=int, default=200, help="small requests per phase")
    ab.add_argument("--small-clients", type=int, default=4)
    ab.add_argument("--uploaders", type=int, default=4)
    ab.add_argument("--uploads", type=int, default=3, help="uploads per uploader")
    ab.add_argument("--upload-samples", type=int, default=2_000_000,
                    help="samples of the even uploaders' float64 .npy (the odd ones send "
                    "5 M, over the limit): fewer are admitted at a higher load")  # fmt: skip
    ab.add_argument("--stalled", type=int, default=300)
    ab.add_argument("--stalled-large", type=int, default=3)
    ab.add_argument("--trickle", type=int, default=200, help="connections trickling headers")
    ab.add_argument("--trickle-s", type=float, default=20.0)
    ab.add_argument("--zeros", type=int, default=1, help="send one 20 MB JSON of zeros (1/0)")
    ab.add_argument("--disconnects", type=int, default=200)
    ab.add_argument("--body-timeout-s", type=float, default=20.0,
                    help="the server's (its default): stalled bodies are cut by its 5 s "
                    "idle timeout anyway, and at load 15-21 this client could not send "
                    "16 MB within 5 s")  # fmt: skip
    ab.add_argument("--deadline", type=float, default=300.0, help="abuse phase limit, s")
    ab.add_argument(
        "--burn",
        type=int,
        default=0,
        help="CPU burner processes running beside the server (a loaded machine)",
    )
    ab.add_argument("--burn-lead-s", type=float, default=45.0,
                    help="seconds the burners run before the first request")  # fmt: skip
    ab.add_argument("--legacy-server", action="store_true",
                    help="the server has no --body-timeout-s (older code; run this "
                    "script from such a checkout to compare)")  # fmt: skip
    args = ap.parse_args()
    if args.quick:
        args.requests, args.clients = 300, 20

    from stiffnet.recordings import read_recording

    rec = read_recording(EXAMPLE)
    samples = rec.accel[: int(args.seconds * rec.fs_hz)]
    body = json.dumps({"samples": np.round(samples, 6).tolist(), "fs_hz": rec.fs_hz,
                       "natural_frequency_hz": float(FN_HZ)}).encode()  # fmt: skip
    if args.abuse:
        return run_abuse(args, body)

    port = free_port()
    base = f"http://127.0.0.1:{port}"
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    cmd = [
        sys.executable,
        "-m",
        "stiffnet",
        "serve",
        "--port",
        str(port),
        "--max-concurrency",
        str(args.max_concurrency),
        "--max-queue",
        str(4 * args.clients),
    ]
    proc = subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        wait_healthy(base, proc)
        warm = httpx.post(
            f"{base}/predict",
            content=body,
            headers={"content-type": "application/json"},
            timeout=60,
        )
        if warm.status_code != 200:
            raise SystemExit(f"warm-up request failed: {warm.status_code} {warm.text[:200]}")
        rss_start = rss_mb(proc.pid)
        res = asyncio.run(run_load(base, body, args.requests, args.clients, proc.pid))
        rss_end = rss_mb(proc.pid)
    finally:
        stop(proc)

    lat = np.array(res["latencies"]) * 1e3
    codes = res["codes"]
    n5xx = sum(v for k, v in codes.items() if isinstance(k, int) and k >= 500)
    n_err = sum(v for k, v in codes.items() if isinstance(k, str))
    print(
        f"{args.requests} requests, {args.clients} concurrent clients, {len(body) / 1e3:.0f} kB "
        f"JSON each ({args.seconds:g} s at {rec.fs_hz:g} Hz), server --max-concurrency "
        f"{args.max_concurrency}"
    )
    print(f"wall {res['wall_s']:.1f} s, throughput {len(lat) / res['wall_s']:.1f} req/s")
    print(
        f"latency ms: p50 {np.percentile(lat, 50):.1f}, p90 {np.percentile(lat, 90):.1f}, "
        f"p99 {np.percentile(lat, 99):.1f}, max {lat.max():.1f} (mean {statistics.fmean(lat):.1f})"
    )
    print(f"status codes: {dict(sorted(codes.items(), key=str))}")
    mid = res["rss"].get("middle", float("nan"))
    print(f"server RSS MB: start {rss_start:.1f}, middle {mid:.1f}, end {rss_end:.1f}")
    print(f"5xx: {n5xx}")
    return 1 if n5xx or n_err else 0


if __name__ == "__main__":
    sys.exit(main())
