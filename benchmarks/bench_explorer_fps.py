"""The explorer's frame loop: frames per second in Chromium, and what a frame costs.

Starts the explorer (``skewpend.views.explorer.create_app``) on a free loopback port, opens it in
Debian's Chromium (Playwright, headless; WebGL by SwiftShader -- software rendering on the CPU,
no GPU on this machine) at two window sizes, lets it run for ``--seconds``, and reports:

* the frames per second the page achieved (requestAnimationFrame, with the generated physics);
* the JavaScript time per frame (integrating, updating the scene, the plots, and issuing the
  WebGL calls) -- the ceiling a GPU-backed browser would reach is 1000 / that;
* the generated physics alone: one RK4 step (4 evaluations of ``rhs`` from /physics.js) in V8,
  and the steps a 60 fps frame needs at speed 1 (dt = 1 ms: 17 steps).

Goal (issue 11): the page's own frame loop at >= 50 fps with the generated physics.

Run:  python benchmarks/bench_explorer_fps.py [--seconds 5]
"""

from __future__ import annotations

import argparse
import socket
import threading
import time

from _common import cpu_model, version  # benchmarks/ is on sys.path when run

ARGS = ["--no-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--no-first-run",
        "--disable-background-networking", "--disable-component-update", "--disable-sync"]


def serve():
    import uvicorn

    from skewpend.views.explorer import create_app

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    server = uvicorn.Server(uvicorn.Config(create_app(), host="127.0.0.1", port=port, log_level="warning"))
    threading.Thread(target=server.run, daemon=True).start()
    while not server.started:
        time.sleep(0.05)
    return server, f"http://127.0.0.1:{port}/"


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seconds", type=float, default=5.0)
    args = ap.parse_args()
    from playwright.sync_api import sync_playwright

    server, url = serve()
    print(f"cpu {cpu_model()}; skewpend {version('skewpend')}, playwright {version('playwright')}, Chromium (Debian), "
          "WebGL by SwiftShader (CPU)")
    print(f"{'window':>12} {'fps':>7} {'JS ms/frame':>12} {'JS-bound fps':>13}")
    with sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path="/usr/bin/chromium", headless=True, args=ARGS)
        for w, h in ((1400, 950), (900, 650)):
            page = browser.new_page(viewport={"width": w, "height": h})
            page.goto(url)
            page.wait_for_function("() => window.explorer && window.explorer.state().frames > 10", timeout=60000)
            f0 = page.evaluate("() => window.explorer.state()")
            t0 = time.perf_counter()
            page.wait_for_timeout(1000 * args.seconds)
            f1 = page.evaluate("() => window.explorer.state()")
            dt = time.perf_counter() - t0
            fps = (f1["frames"] - f0["frames"]) / dt
            ms = f1["frameMs"]
            print(f"{w:>6}x{h:<5} {fps:7.1f} {ms:12.2f} {1000 / ms:13.0f}")
            page.close()
        page = browser.new_page()
        page.goto(url)
        page.wait_for_function("() => window.explorer && window.explorer.state().frames > 2", timeout=60000)
        per_step = page.evaluate("""() => {
            const P = window.explorer.physics, s = window.explorer.state(), p = s.p;
            let y = s.y.slice(); const h = 1e-3, n = 200000;
            const t0 = performance.now();
            for (let i = 0; i < n; i++) {
                const k1 = P.rhs(y, p), k2 = P.rhs(y.map((v, j) => v + 0.5 * h * k1[j]), p);
                const k3 = P.rhs(y.map((v, j) => v + 0.5 * h * k2[j]), p), k4 = P.rhs(y.map((v, j) => v + h * k3[j]), p);
                y = y.map((v, j) => v + h / 6 * (k1[j] + 2 * (k2[j] + k3[j]) + k4[j]));
            }
            return (performance.now() - t0) / n * 1000;  // microseconds per RK4 step
        }""")
        print(f"generated physics in V8: one RK4 step {per_step:.2f} us; a 60 fps frame (17 steps) {17 * per_step / 1000:.3f} ms")
        browser.close()
    server.should_exit = True


if __name__ == "__main__":
    main()
