"""The live explorer under load: the real server (uvicorn, ``create_app()``) on a free loopback port in a
background thread, and N concurrent small requests over TCP (httpx.AsyncClient, one connection each).

The mix: ``POST /api/modes``, ``/api/equations`` and ``/api/simulate`` (t_end = 2 s, dt_out = 0.01) in turn,
over 8 parameter sets (alpha from 0 to 1.4).  Round 1 meets cold caches (each parameter set's equations are
derived once); round 2 repeats the same requests.  The compiled kernel is loaded (or built) before timing.
Goal: 0 errors (any status but 200, or any exception).  Client and server share this process (and its GIL),
so the numbers are a lower bound on what a separate browser would see.

Run:  python benchmarks/bench_explorer_load.py [--n 200]
"""

from __future__ import annotations

import argparse
import asyncio
import os
import platform
import socket
import statistics
import sys
import threading
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import cpu_model, version  # noqa: E402

ALPHAS = (0.0, 0.2, 0.4, 0.6, 0.8, 1.0, 1.2, 1.4)
MODEL = {"a": 1.0, "b": 0.8, "m1": 1.0, "m2": 0.7, "g": 9.81}


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Server:
    """uvicorn serving the explorer in a daemon thread until :meth:`stop`."""

    def __init__(self, app, port: int):
        import uvicorn

        self.server = uvicorn.Server(uvicorn.Config(app, host="127.0.0.1", port=port, log_level="warning",
                                                    lifespan="off", backlog=4096))
        self.thread = threading.Thread(target=self.server.run, name="explorer-server", daemon=True)

    def __enter__(self):
        self.thread.start()
        deadline = time.monotonic() + 30
        while not self.server.started:
            if not self.thread.is_alive() or time.monotonic() > deadline:
                raise SystemExit("the server did not start")
            time.sleep(0.02)
        return self

    def __exit__(self, *exc):
        self.server.should_exit = True
        self.thread.join(timeout=30)


def requests_mix(n: int):
    out = []
    for k in range(n):
        model = {**MODEL, "alpha": ALPHAS[k % len(ALPHAS)]}
        kind = ("modes", "equations", "simulate")[k % 3]
        body = {"model": model}
        if kind == "simulate":
            body.update(t_end=2.0, dt_out=0.01, y0=[1.2, -0.8, 0.0, 0.0])
        out.append((f"/api/{kind}", body))
    return out


async def fire(base: str, jobs):
    import httpx

    limits = httpx.Limits(max_connections=len(jobs), max_keepalive_connections=len(jobs))
    async with httpx.AsyncClient(base_url=base, limits=limits, timeout=120) as client:

        async def one(path, body):
            start = time.perf_counter()
            try:
                r = await client.post(path, json=body)
                ok = r.status_code == 200
                problem = None if ok else f"{r.status_code} {r.text[:120]}"
            except Exception as exc:  # noqa: BLE001 (counted, reported)
                ok, problem = False, f"{type(exc).__name__}: {exc}"
            return path, time.perf_counter() - start, ok, problem

        start = time.perf_counter()
        results = await asyncio.gather(*(one(path, body) for path, body in jobs))
        return time.perf_counter() - start, results


def pct(values, q: float) -> float:
    values = sorted(values)
    return values[min(len(values) - 1, max(0, round(q / 100 * (len(values) - 1))))]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--n", type=int, default=200, help="concurrent requests per round (default 200)")
    args = ap.parse_args()

    import httpx

    from skewpend.views import explorer

    t0 = time.perf_counter()
    app = explorer.create_app()
    created = time.perf_counter() - t0
    port = free_port()
    base = f"http://127.0.0.1:{port}"
    rows, per_path, problems = [], {}, []
    with Server(app, port):
        t0 = time.perf_counter()
        r = httpx.post(f"{base}/api/simulate", json={"t_end": 0.1}, timeout=600)  # loads (or builds) the kernel
        r.raise_for_status()
        warm = time.perf_counter() - t0
        jobs = requests_mix(args.n)
        for label, batch in (("round 1 (cold caches)", jobs), ("round 2 (repeated mix)", jobs)):
            total, results = asyncio.run(fire(base, batch))
            lat = [dt for _, dt, _, _ in results]
            errors = sum(not ok for _, _, ok, _ in results)
            problems += [p for _, _, ok, p in results if not ok][:5]
            rows.append((label, len(results), errors, total, len(results) / total,
                         pct(lat, 50), pct(lat, 95), max(lat)))
            for path, dt, _, _ in results:
                per_path.setdefault((label, path), []).append(dt)

    print("machine")
    print(f"  cpu        {cpu_model()}")
    print(f"  cores      {len(os.sched_getaffinity(0)) if hasattr(os, 'sched_getaffinity') else os.cpu_count()} usable "
          f"(os.cpu_count {os.cpu_count()}); load average {os.getloadavg()[0]:.2f} at end")
    print(f"  python     {platform.python_version()}   skewpend {version('skewpend')}   fastapi {version('fastapi')}   "
          f"uvicorn {version('uvicorn')}   httpx {version('httpx')}")
    print(f"server: uvicorn on 127.0.0.1:{port} in a thread of this process; HEAVY_SLOTS = {explorer.HEAVY_SLOTS}, "
          f"TIME_LIMIT = {explorer.TIME_LIMIT:g} s")
    print(f"create_app {created:.2f} s; first simulate (kernel load or build) {warm:.2f} s (untimed below)")
    print(f"mix: {args.n} concurrent POSTs per round, modes / equations / simulate (t_end = 2 s) in turn, "
          f"{len(ALPHAS)} parameter sets\n")
    print(f"{'round':24s} {'requests':>8s} {'errors':>6s} {'total s':>8s} {'req/s':>7s} {'p50 ms':>8s} {'p95 ms':>8s} "
          f"{'max ms':>8s}  goal: 0 errors")
    for label, n, errors, total, rate, p50, p95, mx in rows:
        print(f"{label:24s} {n:8d} {errors:6d} {total:8.2f} {rate:7.1f} {p50 * 1e3:8.1f} {p95 * 1e3:8.1f} {mx * 1e3:8.1f}"
              f"  {'PASS' if errors == 0 else 'FAIL'}")
    print(f"\n{'round / endpoint':45s} {'n':>4s} {'p50 ms':>8s} {'max ms':>8s}")
    for (label, path), lat in per_path.items():
        print(f"{label.split(' (')[0] + ' ' + path:45s} {len(lat):4d} {statistics.median(lat) * 1e3:8.1f} "
              f"{max(lat) * 1e3:8.1f}")
    for p in problems:
        print("error:", p)


if __name__ == "__main__":
    main()
