"""The explorer after a slider moves (issue 37's goal: a mass, length or inertia changed without compiling,
new motion within 0.2 s).

In the page the motion runs on the generated JavaScript (``physics.js``), whose parameter array the
sliders change synchronously (``app.js``, ``setValue``): the next animation frame moves with the new
values, with no request and nothing compiled.  What a change costs on the server is measured here: the
explorer's app (``create_app()``, in process through FastAPI's test client) is warmed with the default
model, then each request changes one value -- m1, m2, a, b, g, the damping -- to a value not seen before
(so no result is cached) and asks ``POST /api/simulate`` for the default 10 s at dt_out 0.01, and
``POST /api/equations`` and ``/api/modes`` (what the page asks 250 ms after the last move).  Printed per
endpoint: min, median, max over the changes, and whether any compile note appeared.

Run:  python benchmarks/bench_explorer_params.py [--changes 12]
"""

from __future__ import annotations

import argparse
import contextlib
import io
import statistics
import time


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--changes", type=int, default=12)
    args = ap.parse_args()
    from fastapi.testclient import TestClient

    from skewpend.views.explorer import create_app

    client = TestClient(create_app())
    base = {"a": 1.0, "b": 0.8, "m1": 1.0, "m2": 0.7, "g": 9.81}
    for path in ("/api/simulate", "/api/equations", "/api/modes"):  # warm: the kernel, the first derivation
        assert client.post(path, json={"model": base}).status_code == 200
    keys = ("m1", "m2", "a", "b", "g", "c1")
    times = {p: [] for p in ("/api/simulate", "/api/equations", "/api/modes")}
    notes = io.StringIO()
    with contextlib.redirect_stderr(notes):
        for i in range(args.changes):
            key = keys[i % len(keys)]
            model = dict(base)
            model[key] = (base.get(key, 0.0) or 0.05) * (1.0 + 0.037 * (i + 1))
            for path in times:
                t0 = time.perf_counter()
                r = client.post(path, json={"model": model})
                times[path].append(time.perf_counter() - t0)
                assert r.status_code == 200, (path, r.text)
    for path, v in times.items():
        print(f"{path:16s} min {1e3 * min(v):7.1f}  median {1e3 * statistics.median(v):7.1f}  "
              f"max {1e3 * max(v):7.1f} ms over {len(v)} changed values")
    compiled = [line for line in notes.getvalue().splitlines() if "compiling" in line]
    print(f"compile notes during the changes: {len(compiled)}")


if __name__ == "__main__":
    main()
