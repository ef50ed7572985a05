"""The explorer server (``skewpend serve``) against hostile clients (issue 20, class 8), over real
sockets on 127.0.0.1 / ::1 only, every loop bounded and every wait with a time limit:

* a request body is limited by what is *read*: a chunked body far over :data:`MAX_BODY` is
  refused with 422 once the cap is passed, and the server's memory does not grow with it;
* connections that never complete their request headers are closed within HEADER_TIMEOUT;
* the Host header must name the server (DNS rebinding), else 400;
* no page loads anything from another machine (no Swagger UI from a CDN: /docs is 404);
* Ctrl-C or SIGTERM while a heavy request computes stops the server (exit 130 / 143, as every
  command) without finishing the work (it used to wait for it), the port free again;
* the address checks of :func:`explorer.serve` / :func:`explorer.check_address`: one
  :class:`ParameterError` naming host or port, URLs with IPv6 in brackets.
"""

from __future__ import annotations

import json
import selectors
import signal
import socket
import subprocess
import sys
import threading
import time

import pytest

pytest.importorskip("fastapi")
pytest.importorskip("uvicorn")

from skewpend.errors import ParameterError  # noqa: E402
from skewpend.views import explorer  # noqa: E402

START_LIMIT = 60.0  # s for the server to start (imports, the generated physics) on a busy machine


def _free_port(family=socket.AF_INET, host="127.0.0.1") -> int:
    with socket.socket(family) as s:
        s.bind((host, 0))
        return s.getsockname()[1]


def _start(host="127.0.0.1"):
    """``skewpend serve`` in a subprocess on a free port: (process, port) once it answers."""
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    for _ in range(3):  # a port taken between the probe and the start: another one
        port = _free_port(family, host)
        proc = subprocess.Popen([sys.executable, "-m", "skewpend", "serve", "--host", host, "--port", str(port)],
                                stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        deadline = time.monotonic() + START_LIMIT
        while time.monotonic() < deadline and proc.poll() is None:
            try:
                socket.create_connection((host, port), timeout=0.5).close()
                return proc, port
            except OSError:
                time.sleep(0.1)
        proc.kill()
        proc.wait(10)
    pytest.fail(f"the server did not start: {proc.stderr.read().decode()[-500:]}")


def _stop(proc) -> None:
    if proc.poll() is None:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(10)
    proc.stderr.close()


@pytest.fixture(scope="module")
def server():
    proc, port = _start()
    yield proc, port
    _stop(proc)


def _rss(pid: int) -> int:
    """Resident memory of a process [bytes] (Linux)."""
    with open(f"/proc/{pid}/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) * 1024
    raise RuntimeError("no VmRSS")


def _read_answer(sock, limit=10.0) -> bytes:
    """Everything the server sends until it closes or ``limit`` s pass (a reset ends it too)."""
    sock.settimeout(limit)
    data = b""
    deadline = time.monotonic() + limit
    try:
        while time.monotonic() < deadline:
            part = sock.recv(65536)
            if not part:
                break
            data += part
            if b"\r\n\r\n" in data:
                head, _, body = data.partition(b"\r\n\r\n")
                length = [int(l.split(b":")[1]) for l in head.lower().split(b"\r\n") if l.startswith(b"content-length:")]
                if length and len(body) >= length[0]:
                    break
    except (socket.timeout, ConnectionResetError):
        pass
    return data


def _status(answer: bytes) -> int:
    assert answer.startswith(b"HTTP/1.1 "), answer[:200]
    return int(answer.split()[1])


def _request(port, raw: bytes, host="127.0.0.1") -> bytes:
    with socket.create_connection((host, port), timeout=10) as s:
        s.sendall(raw)
        return _read_answer(s)


def _get(port, path="/api/version", host_header=None):
    host_header = f"127.0.0.1:{port}" if host_header is None else host_header
    return _request(port, f"GET {path} HTTP/1.1\r\nHost: {host_header}\r\nConnection: close\r\n\r\n".encode())


# -- the request body: limited by what is read ------------------------------------------------------------
MODES = json.dumps({"model": {"alpha": 0.3}}).encode()


@pytest.mark.parametrize("total, piece", [
    (32 * 1024 * 1024, 8192),  # 32 MB in 8 kB chunks (an 8 MB body was answered 200, 256 MB read)
    (4 * 1024 * 1024, 1024 * 1024),  # 1 MB chunks: a single chunk over the cap
    (explorer.MAX_BODY + 1, explorer.MAX_BODY + 1),  # one byte over, in one chunk
    (explorer.MAX_BODY + 1, 1000),  # one byte over, in many
])
def test_a_chunked_body_over_the_cap_is_refused_and_not_read(server, total, piece):
    proc, port = server
    before = _rss(proc.pid)
    with socket.create_connection(("127.0.0.1", port), timeout=10) as s:
        s.sendall(f"POST /api/modes HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nContent-Type: application/json\r\n"
                  "Transfer-Encoding: chunked\r\n\r\n".encode())
        sent, answered = 0, b""
        sel = selectors.DefaultSelector()
        sel.register(s, selectors.EVENT_READ)
        try:
            while sent < total:  # bounded: total bytes at most
                n = min(piece, total - sent)
                s.sendall(b"%x\r\n" % n + b" " * n + b"\r\n")
                sent += n
                if sel.select(timeout=0):
                    break
            else:
                s.sendall(b"0\r\n\r\n")
        except (BrokenPipeError, ConnectionResetError):
            pass  # the server stopped reading: what it sent is read below
        answered = _read_answer(s)
        sel.close()
    assert _status(answered) == 422, answered[:300]
    body = json.loads(answered.partition(b"\r\n\r\n")[2])
    assert f"at most {explorer.MAX_BODY} bytes" in body["detail"][0]["msg"]
    assert b"connection: close" in answered.lower()  # the rest of the body is not read
    grown = _rss(proc.pid) - before
    assert grown < 8 * 1024 * 1024, f"the server grew by {grown / 1e6:.1f} MB for a {total / 1e6:.1f} MB body"
    assert _status(_get(port)) == 200  # and it goes on serving


@pytest.mark.parametrize("pieces", [[MODES], [MODES[:5], MODES[5:17], MODES[17:]], [bytes([b]) for b in MODES]])
def test_a_chunked_body_under_the_cap_is_served(server, pieces):
    _, port = server
    chunks = b"".join(b"%x\r\n%s\r\n" % (len(p), p) for p in pieces) + b"0\r\n\r\n"
    answer = _request(port, f"POST /api/modes HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nContent-Type: application/json\r\n"
                            "Transfer-Encoding: chunked\r\nConnection: close\r\n\r\n".encode() + chunks)
    assert _status(answer) == 200, answer[:300]
    assert "frequencies" in json.loads(answer.partition(b"\r\n\r\n")[2])


@pytest.mark.parametrize("length", [str(explorer.MAX_BODY + 1), "9" * 40, "-1", "1e9"])
def test_a_content_length_over_the_cap_is_refused_before_reading(server, length):
    _, port = server
    answer = _request(port, f"POST /api/modes HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: application/json\r\n"
                            f"Content-Length: {length}\r\n\r\n{{".encode())
    assert _status(answer) in (400, 422), answer[:300]  # 400: h11 refuses a malformed length itself


def test_an_endless_header_is_refused_once_it_passes_16_kb(server):
    _, port = server
    answer = _request(port, f"GET / HTTP/1.1\r\nHost: 127.0.0.1\r\nX-Big: {'a' * 100_000}".encode())
    assert _status(answer) == 400, answer[:300]


# -- incomplete headers ---------------------------------------------------------------------------------------
PARTIAL = [b"", b"GET / HT", b"GET / HTTP/1.1\r\nHost: 127.0.0.1\r\n", b"POST /api/modes HTTP/1.1\r\nX-a: "]


def test_connections_with_incomplete_headers_are_closed(server):
    """50 connections that never finish their headers (one of them trickling a byte a second) are
    closed within HEADER_TIMEOUT (+ slack) -- they were held for ever."""
    _, port = server
    socks, sel = [], selectors.DefaultSelector()
    try:
        for k in range(50):
            s = socket.create_connection(("127.0.0.1", port), timeout=5)
            s.sendall(PARTIAL[k % len(PARTIAL)])
            s.setblocking(False)
            sel.register(s, selectors.EVENT_READ, k)
            socks.append(s)
        trickler = socks[3]  # sends a header byte every 0.5 s: that resets no deadline
        start = time.monotonic()
        # a hang guard, not a speed test (they were held for ever); the server's own timer closes them
        limit = explorer.HEADER_TIMEOUT + 30.0
        open_ = set(range(len(socks)))
        last_trickle = start
        while open_ and time.monotonic() - start < limit:
            for key, _ in sel.select(timeout=0.1):
                try:
                    data = key.fileobj.recv(4096)
                except (BlockingIOError, InterruptedError):
                    continue
                except ConnectionResetError:
                    data = b""
                if not data or b"connection: close" in data.lower() or data.startswith(b"HTTP/1.1 408"):
                    if key.data in open_:
                        open_.discard(key.data)
                        sel.unregister(key.fileobj)
            if 3 in open_ and time.monotonic() - last_trickle > 0.5:
                try:
                    trickler.send(b"a")
                except OSError:
                    pass
                last_trickle = time.monotonic()
        elapsed = time.monotonic() - start
        assert not open_, f"{len(open_)} of 50 connections still open after {elapsed:.1f} s"
        assert elapsed >= explorer.HEADER_TIMEOUT - 1.0  # not closed before their time (load only delays it)
    finally:
        sel.close()
        for s in socks:
            s.close()
    assert _status(_get(port)) == 200


def test_a_keep_alive_connection_gets_its_next_request_answered(server):
    """The header deadline restarts after each answer: a client that reuses its connection is served."""
    _, port = server
    with socket.create_connection(("127.0.0.1", port), timeout=10) as s:
        for _ in range(3):
            s.sendall(f"GET /api/version HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\n\r\n".encode())
            assert _status(_read_answer(s)) == 200


# -- the Host header ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("host_header, status", [
    ("127.0.0.1:{port}", 200), ("127.0.0.1", 200), ("localhost", 200), ("localhost:{port}", 200),
    ("LOCALHOST:{port}", 200), ("[::1]:{port}", 200), ("[::1]", 200),
    ("evil.example", 400), ("evil.example:{port}", 400), ("127.0.0.1.evil.example", 400),
    ("127.0.0.1:{other}", 400), ("localhost:abc", 400), ("[::1", 400), ("[::1]x", 400), ("10.0.0.1", 400),
    ("", 400),
])
def test_the_host_header_must_name_this_server(server, host_header, status):
    _, port = server
    answer = _get(port, host_header=host_header.format(port=port, other=port + 1 if port < 65535 else 1))
    assert _status(answer) == status, answer[:300]
    if status == 400:
        assert b"Host header" in answer


def test_a_request_without_a_host_header_is_refused(server):
    _, port = server
    assert _status(_request(port, b"GET /api/version HTTP/1.0\r\n\r\n")) == 400


@pytest.mark.parametrize("bound, names, allowed, refused", [
    ("127.0.0.1", ["127.0.0.1", "localhost", "[::1]"], [], ["evil.example", "192.168.1.2"]),
    ("::1", ["[::1]", "localhost", "127.0.0.1"], [], ["evil.example"]),
    ("192.0.2.7", ["192.0.2.7"], [], ["localhost", "evil.example", "192.0.2.8"]),
    ("0.0.0.0", ["192.168.1.2", "[fe80::1]", "localhost"], [], ["evil.example", "*ip"]),
])
def test_the_hosts_allowed_for_each_bind(bound, names, allowed, refused):
    hosts = explorer._allowed_hosts(bound)
    for name in names + allowed:
        assert explorer._host_allowed(f"{name}:8000".encode(), hosts, 8000), name
        assert explorer._host_allowed(name.encode(), hosts, 8000), name
    for name in refused:
        assert not explorer._host_allowed(name.encode(), hosts, 8000), name


# -- nothing leaves the machine ----------------------------------------------------------------------------------
@pytest.mark.parametrize("path, status", [("/docs", 404), ("/redoc", 404), ("/docs/oauth2-redirect", 404),
                                          ("/openapi.json", 200), ("/", 200)])
def test_no_page_loads_anything_from_another_machine(server, path, status):
    _, port = server
    answer = _get(port, path)
    assert _status(answer) == status
    body = answer.partition(b"\r\n\r\n")[2].lower()
    assert b"cdn" not in body and b"https://" not in body and b"//unpkg" not in body


# -- Ctrl-C and SIGTERM while busy -----------------------------------------------------------------------------
@pytest.mark.parametrize("signum, code, word", [(signal.SIGINT, 130, b"interrupted"), (signal.SIGTERM, 143, b"terminated")])
def test_a_signal_while_busy_stops_the_server_within_a_second(signum, code, word):
    """The work in flight is cancelled, not finished: its answer is 503 or none, never the result (the
    server used to wait 8 s for it) -- shown by the answer, not by the seconds (issue 36)."""
    proc, port = _start()
    answers = []
    try:
        body = json.dumps({"model": {"tau2": 1000.0}, "t_end": 100.0, "dt_out": 0.01}).encode()

        def heavy():  # several seconds of work
            answers.append(_request(port, f"POST /api/simulate HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: "
                                          f"application/json\r\nContent-Length: {len(body)}\r\n\r\n".encode() + body))

        worker = threading.Thread(target=heavy, daemon=True)
        worker.start()
        time.sleep(1.0)  # the work is under way
        assert not answers, "the heavy request finished too early to test anything"
        start = time.monotonic()
        proc.send_signal(signum)
        returncode = proc.wait(30)  # a hang guard, not a speed test (see the answer below)
        elapsed = time.monotonic() - start
        err = proc.stderr.read()
        worker.join(10)
    finally:
        _stop(proc)
    assert returncode == code, err
    assert err.strip().endswith(b"skewpend: " + word) and b"Traceback" not in err, err
    print(f"stopped {elapsed:.1f} s after the signal")
    assert answers and (answers[0] == b"" or _status(answers[0]) == 503), answers[:1]  # not the result
    with socket.socket() as again:  # nothing left listening (SO_REUSEADDR: closed connections may linger in TIME_WAIT)
        again.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        again.bind(("127.0.0.1", port))


# -- the address checks of the library ------------------------------------------------------------------------
@pytest.mark.parametrize("host, expected", [
    ("127.0.0.1", "127.0.0.1"), ("::1", "::1"), ("[::1]", "::1"), (" localhost ", "localhost"),
    ("LocalHost", "localhost"), ("0:0:0:0:0:0:0:1", "::1"), ("127.1.2.3", "127.1.2.3"), ("0.0.0.0", "0.0.0.0"),
])
def test_check_host_accepts(host, expected):
    assert explorer.check_host(host) == expected


@pytest.mark.parametrize("host", ["", "   ", "[::1", "::1]", "hôst", "no such host!", "a" * 300, None, 127, "[localhost]",
                                  "-bad", "bad-"])
def test_check_host_refuses_in_one_line(host):
    with pytest.raises(ParameterError) as info:
        explorer.check_host(host)
    assert info.value.parameter == "host" and "\n" not in str(info.value)


@pytest.mark.parametrize("host, loopback, url", [
    ("127.0.0.1", True, "http://127.0.0.1:{port}/"), ("::1", True, "http://[::1]:{port}/"),
    ("[::1]", True, "http://[::1]:{port}/"), ("localhost", True, "http://localhost:{port}/"),
    ("127.0.0.2", True, "http://127.0.0.2:{port}/"), ("0.0.0.0", False, "http://127.0.0.1:{port}/"),
])
def test_check_address_url_and_loopback(host, loopback, url):
    if ":" in host and not socket.has_ipv6:
        pytest.skip("no IPv6 on this machine")
    address = explorer.check_address(host, 0)
    assert address.loopback is loopback and (address.warning is None) is loopback
    assert address.url == url.format(port=address.port) and 0 < address.port < 65536


@pytest.mark.parametrize("host, port, parameter", [
    ("127.0.0.1", "²", "port"), ("127.0.0.1", "٨٠٠٠", "port"), ("127.0.0.1", 70000, "port"), ("127.0.0.1", -1, "port"),
    ("127.0.0.1", 80.5, "port"), ("127.0.0.1", True, "port"), ("127.0.0.1", "9" * 5000, "port"),
    ("[::1", 8000, "host"), ("192.0.2.1", 0, "host"),  # TEST-NET: not an address of this machine
])
def test_serve_refuses_bad_addresses_before_starting(host, port, parameter, monkeypatch):
    monkeypatch.setattr(explorer, "create_app", lambda **kw: pytest.fail("started"))
    with pytest.raises(ParameterError) as info:
        explorer.serve(host, port)
    assert info.value.parameter == parameter and "\n" not in str(info.value)


def test_serve_refuses_a_busy_port_in_one_line(monkeypatch):
    monkeypatch.setattr(explorer, "create_app", lambda **kw: pytest.fail("started"))
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        with pytest.raises(ParameterError) as info:
            explorer.serve("127.0.0.1", port)
    assert info.value.parameter == "port" and f"127.0.0.1:{port}" in str(info.value)


@pytest.mark.parametrize("argv, words", [
    (["--host", "192.0.2.1"], "--host"), (["--port", "²"], "--port"), (["--host", "[::1"], "--host"),
])
def test_the_command_refuses_bad_addresses_in_one_line(argv, words):
    ran = subprocess.run([sys.executable, "-m", "skewpend", "serve", *argv], capture_output=True, text=True, timeout=60,
                         stdin=subprocess.DEVNULL)
    assert ran.returncode == 2, ran.stderr
    from skewpend.progress import STAGE_LINE

    # a stage line may come first ("skewpend serve: starting the explorer..." once the command is slower than its
    # first-line deadline, e.g. a bind that waits): the error is then the one other line
    err = "".join(line + "\n" for line in ran.stderr.splitlines() if not STAGE_LINE.match(line))
    assert err.startswith("skewpend: error:") and err.count("\n") == 1 and words in err, ran.stderr


@pytest.mark.skipif(not socket.has_ipv6, reason="no IPv6 on this machine")
def test_serving_on_ipv6_loopback_prints_a_bracketed_url_and_answers():
    try:
        proc, port = _start("::1")
    except OSError:
        pytest.skip("::1 cannot be bound here")
    try:
        from skewpend.progress import STAGE_LINE

        line = proc.stderr.readline().decode()
        while STAGE_LINE.match(line.rstrip("\n")):  # the stage said while it starts, then the address
            line = proc.stderr.readline().decode()
        assert line == f"skewpend explorer on http://[::1]:{port}/ (Ctrl-C to stop)\n", line
        with socket.create_connection(("::1", port), timeout=10) as s:
            s.sendall(f"GET /api/version HTTP/1.1\r\nHost: [::1]:{port}\r\nConnection: close\r\n\r\n".encode())
            assert _status(_read_answer(s)) == 200
    finally:
        _stop(proc)


def test_serve_in_a_thread_stops_when_told():
    """``serve(..., ready=, stop=)``: the address once listening; setting ``stop`` ends it as Ctrl-C does."""
    started, stop = [], threading.Event()
    thread = threading.Thread(target=explorer.serve, args=("localhost", 0), kwargs={"ready": started.append, "stop": stop},
                              daemon=True)
    thread.start()
    deadline = time.monotonic() + START_LIMIT
    while not started and thread.is_alive() and time.monotonic() < deadline:
        time.sleep(0.05)
    assert started, "the server did not start"
    address = started[0]
    assert address.url == f"http://localhost:{address.port}/" and address.loopback
    assert _status(_get(address.port, host_header=f"localhost:{address.port}")) == 200
    stop.set()
    thread.join(30)  # a hang guard, not a speed test: it stops at all, as on Ctrl-C
    assert not thread.is_alive()
