"""The live explorer: a local web app over the library (``skewpend serve``; the ``web`` extra).

The page (``web/index.html``, ``web/app.js``) is the same front end as the static explorer
(:func:`skewpend.views.frontend.export_explorer`): it draws the moving pendulum in 3D with three.js
-- bundled in the package from the npm ``three`` package, never loaded from a CDN -- and computes
everything it shows in the browser with the JavaScript *generated from the derivation*
(:func:`skewpend.numeric.explorer_source.explorer_js`): the motion, the equations for the current
parameters, the normal modes and the flip map (in Web Workers).  The server delivers the page's
files (``/sources/*.js``: the registrations of :mod:`skewpend.views.frontend`; the generated
module alone is ``/physics.js``) and, for programs, a JSON API with the library's compiled
computations, documented by its OpenAPI schema (``/openapi.json``; there is no ``/docs`` page:
FastAPI's Swagger UI loads its scripts from a CDN, and the explorer never makes a request leave
the machine):

* ``POST /api/equations`` -- the equations of motion for the current parameters (LaTeX);
* ``POST /api/simulate`` -- a trajectory (DOP853, compiled), with the energy;
* ``POST /api/modes`` -- the normal modes (frequencies, shapes);
* ``POST /api/flipmap`` -- a small flip-time map (compiled DOP853).

Safety: the server binds 127.0.0.1 unless told otherwise; every request is validated (bad input, and bad
parameters the library finds, -> HTTP 422 with a message naming the field); what a request and a client may
ask for and hold is bounded (the constants below: larger requests are refused at once, slow ones timed
out); heavy work runs in at most :data:`HEAVY_SLOTS` worker threads, each within :data:`TIME_LIMIT` s (then
503); the ``Host`` header must name the server (DNS rebinding), else 400; on Ctrl-C or SIGTERM in-flight
work is cancelled and the server stops within about a second.
"""

import asyncio
import math
import threading
from contextlib import suppress
from functools import lru_cache
from pathlib import Path
from typing import Any, Dict, List

from .. import __version__, schema
from ..errors import SkewpendError

__all__ = ["create_app", "serve", "check_host", "check_address", "Address", "LIMITS", "TIME_LIMIT", "HEAVY_SLOTS",
           "MAX_BODY", "HEADER_TIMEOUT", "BODY_TIMEOUT", "MAX_CONNECTIONS", "require_web", "WEB_EXTRA"]

WEB_EXTRA = 'pip install "skewpend[web]"'
#: Bounds on the work one request may ask for.
LIMITS = {
    "simulate_t_end": 120.0,  # s of motion
    "simulate_points": 20_001,  # output rows (t_end / dt_out + 1)
    "simulate_steps": 2_000_000,  # integrator steps
    "flipmap_n": 96,  # cells per side
    "flipmap_t_end": 30.0,  # s
    "flipmap_cells_time": 96 * 96 * 10.0,  # n^2 x t_end [cell-seconds]
    "flipmap_cell_steps": 20_000,  # integrator steps per cell (a cell that needs more counts as failed)
}
#: Largest request body [bytes].
MAX_BODY = 65_536
#: Seconds a heavy request may take before it is answered with 503.
TIME_LIMIT = 20.0
#: Heavy requests computed at the same time (the others wait their turn).
HEAVY_SLOTS = 2
#: Seconds a connection may take to send a request's complete headers (then it is closed).
HEADER_TIMEOUT = 5.0
#: Seconds a request's body may take to arrive (then 408).
BODY_TIMEOUT = 10.0
#: Requests handled at the same time by :func:`serve` (uvicorn's ``limit_concurrency``: the others get 503).
MAX_CONNECTIONS = 256
#: Seconds :func:`serve` waits at shutdown for answers in flight (their work is cancelled at once).
SHUTDOWN_GRACE = 1.0
_WEB = Path(__file__).resolve().parent / "web"


#: The error answers of the API (besides FastAPI's own 422 for invalid requests).
_ERRORS = {422: {"description": "invalid input: detail names the field and what is allowed"},
           503: {"description": "the computation took longer than the time limit"}}


class _Deadline(Exception):
    """Raised in a worker thread whose request ran out of time."""


class _Guard:
    """The ASGI middleware in front of the app: the ``Host`` header (when ``hosts`` is given) and
    the request body, counted as it is *read* from the server -- a ``Content-Length`` over
    :data:`MAX_BODY` is refused before reading, a chunked body as soon as it passes it; at most
    MAX_BODY bytes are ever held.  The body is then replayed to the app."""

    def __init__(self, app, hosts=None, port=None):
        self.app, self.hosts, self.port = app, hosts, port

    async def __call__(self, scope, receive, send):
        if scope["type"] != "http":
            return await self.app(scope, receive, send)
        headers = dict(scope.get("headers") or ())
        if self.hosts is not None and not _host_allowed(headers.get(b"host"), self.hosts, self.port):
            return await _answer(send, 400, "the Host header must name this server (e.g. 127.0.0.1 or localhost)")
        size = headers.get(b"content-length")
        if size is not None and (not size.isdigit() or int(size) > MAX_BODY):
            return await _answer(send, 422, f"the request body must be at most {MAX_BODY} bytes", close=True)
        body, more = bytearray(), True
        loop = asyncio.get_running_loop()
        deadline = loop.time() + BODY_TIMEOUT
        while more:
            try:
                message = await asyncio.wait_for(receive(), timeout=max(deadline - loop.time(), 0.0))
            except asyncio.TimeoutError:
                return await _answer(send, 408, f"the request body did not arrive within {BODY_TIMEOUT:g} s", close=True)
            if message["type"] != "http.request":  # the client left
                return None
            body += message.get("body", b"")
            more = message.get("more_body", False)
            if len(body) > MAX_BODY:
                return await _answer(send, 422, f"the request body must be at most {MAX_BODY} bytes", close=True)
        replayed = False

        async def replay():
            nonlocal replayed
            if not replayed:
                replayed = True
                return {"type": "http.request", "body": bytes(body), "more_body": False}
            return await receive()

        return await self.app(scope, replay, send)


async def _answer(send, status: int, message: str, close: bool = False) -> None:
    """A JSON error answer (``close``: and the connection is closed, the rest of the body unread)."""
    import json

    content = ({"detail": [{"loc": ["body"], "msg": message, "type": "value_error"}]} if status == 422
               else {"detail": message})
    data = json.dumps(content).encode()
    headers = [(b"content-type", b"application/json"), (b"content-length", str(len(data)).encode())]
    if close:
        headers.append((b"connection", b"close"))
    await send({"type": "http.response.start", "status": status, "headers": headers})
    await send({"type": "http.response.body", "body": data, "more_body": False})


def _host_allowed(value, hosts, port) -> bool:
    """Whether a ``Host`` header (bytes or None) names one of ``hosts`` (lower case; IPv6 without
    brackets; ``"*ip"`` allows every IP literal), with no port or ``port``."""
    import ipaddress

    if not value:
        return False
    try:
        text = value.decode("ascii").strip().lower()
    except UnicodeDecodeError:
        return False
    if text.startswith("["):
        name, bracket, rest = text[1:].partition("]")
        if not bracket or (rest and not rest.startswith(":")):
            return False
        given = rest[1:] if rest else None
    else:
        name, colon, given = text.partition(":")
        given = given if colon else None
    if given is not None and not (given.isdigit() and port is not None and int(given) == port):
        return False
    if name in hosts and name != "*ip":
        return True
    if "*ip" in hosts:
        with suppress(ValueError):
            ipaddress.ip_address(name)
            return True
    return False


def require_web(what: str = "the explorer"):
    """FastAPI and uvicorn, or one clear :class:`SkewpendError` naming the extra to install."""
    try:
        import fastapi  # noqa: F401
        import uvicorn  # noqa: F401
    except ImportError:
        raise SkewpendError(f"{what} needs FastAPI and uvicorn, which are not installed: {WEB_EXTRA}") from None


#: The parameters the API's requests take (no Coulomb friction or rotors: a page shows them only from its physics'
#: model, ``skewpend serve --config``).
API_PARAMETERS = schema.CORE_NAMES + schema.DAMPING_NAMES + schema.TORQUE_NAMES
#: The largest value the API takes of a parameter, by its unit (the negative limit too for a real one).
API_LIMITS = {"m": 10, "kg": 100, "rad": 2 * math.pi, "m/s²": 100, "N m s": 100, "N m": 1000}


def _models():
    """The request models (pydantic), built on first use so that importing this module is cheap."""
    from typing import Annotated

    from pydantic import BaseModel, ConfigDict, Field, create_model

    from ..config import DEFAULT_RUN

    Entry = Annotated[float, Field(ge=-1000, le=1000)]
    reference = DEFAULT_RUN["parameters"]

    def parameter(name: str):
        """The API's field of the parameter ``name``: the schema's bound, the explorer's limit of its unit."""
        f = schema.field(name)
        top = API_LIMITS[f.unit]
        low = {"gt": 0} if f.bound == "positive" else {"ge": 0} if f.bound == "nonnegative" else {"ge": -top}
        default = reference.get(name, schema.default(name))
        return (float, Field(default, le=top, description=f"{schema.meaning(name)} [{f.unit}]", **low))

    Model = create_model("Model", __config__=ConfigDict(extra="forbid", allow_inf_nan=False, strict=True),
                         __doc__="The pendulum: thin uniform rods with the specification's hinge axes (SI units, radians).",
                         **{name: parameter(name) for name in API_PARAMETERS})

    class Request(BaseModel):
        model_config = ConfigDict(extra="forbid", allow_inf_nan=False, strict=True)
        model: Model = Field(default_factory=Model)

    class EquationsRequest(Request):
        digits: int = Field(4, ge=2, le=8, description="significant digits of the numbers shown")

    class SimulateRequest(Request):
        y0: List[Entry] = Field([1.2, -0.8, 0.0, 0.0], min_length=4, max_length=4,
                                description="initial state (phi, psi, dphi, dpsi) [rad, rad/s], each at most 1000")
        t_end: float = Field(10.0, gt=0, le=LIMITS["simulate_t_end"], description="length [s]")
        dt_out: float = Field(0.01, gt=0, le=LIMITS["simulate_t_end"], description="output interval [s]")
        rtol: float = Field(1e-10, ge=1e-14, le=1e-3, description="relative tolerance of DOP853")
        atol: float = Field(1e-10, ge=1e-14, le=1e-3, description="absolute tolerance of DOP853")

    class ModesRequest(Request):
        pass

    class FlipMapRequest(Request):
        n: int = Field(48, ge=2, le=LIMITS["flipmap_n"], description="cells per side")
        t_end: float = Field(10.0, gt=0, le=LIMITS["flipmap_t_end"], description="longest time looked at [s]")

    return Model, EquationsRequest, SimulateRequest, ModesRequest, FlipMapRequest


def _params(model):
    from ..symbolic.model import Parameters

    return Parameters(**model.model_dump())


def _finite(values) -> list:
    """A JSON-ready list with NaN and infinities as null."""
    import numpy as np

    arr = np.asarray(values, dtype=float)
    out = arr.astype(object)
    out[~np.isfinite(arr)] = None
    return out.tolist()


@lru_cache(maxsize=256)
def _equations(values: tuple, digits: int) -> Dict[str, Any]:
    """The equations of the model ``values`` (its (name, value) pairs: hashable, for the cache)."""
    from ..symbolic.derivation import derive
    from ..symbolic.model import Parameters
    from ..symbolic.layout import equations_tex, numeric
    from ..symbolic.render import tex

    params = Parameters(**dict(values))
    eom = derive(params)
    M, f = numeric(eom.mass_matrix, digits), numeric(eom.forcing, digits)
    return {
        "latex": equations_tex(M, f, tex),
        "M": [[tex(M[i, j]) for j in range(2)] for i in range(2)],
        "f": [tex(f[i]) for i in range(2)],
        "T": tex(numeric(eom.kinetic_energy, digits)),
        "Pi": tex(numeric(eom.potential_energy, digits)),
        "digits": digits,
    }


def create_app(*, physics_params=None, hosts=None, port=None):
    """The FastAPI application.  ``physics_params``: the bodies and axes whose generated
    JavaScript the page integrates (default: the specification's thin rods).  ``hosts``: the
    names the ``Host`` header may give (lower case, IPv6 without brackets; ``"*ip"``: any IP
    address), with no port or ``port``; others get 400 (None: any host, for use in process;
    :func:`serve` passes the names of its address).  ``app.state.stopping`` (a
    :class:`threading.Event`) cancels every computation in flight when set (503)."""
    require_web()
    from fastapi import FastAPI, HTTPException, Request
    from fastapi.exceptions import RequestValidationError
    from fastapi.responses import FileResponse, JSONResponse, Response
    from starlette.exceptions import HTTPException as StarletteHTTPException
    from fastapi.staticfiles import StaticFiles
    from starlette.concurrency import run_in_threadpool

    from .frontend import katex_dir, registration, sources

    _, EquationsRequest, SimulateRequest, ModesRequest, FlipMapRequest = _models()
    page_sources = sources(physics_params)
    physics = page_sources["physics"].code
    registrations = {name: registration(src) for name, src in page_sources.items()}
    slots = threading.BoundedSemaphore(HEAVY_SLOTS)
    stopping = threading.Event()

    app = FastAPI(
        title="skewpend explorer",
        version=__version__,
        docs_url=None,  # Swagger UI and ReDoc load scripts from a CDN: only the schema, /openapi.json
        redoc_url=None,
        description="The double pendulum with skewed hinge axes: equations, simulation, normal modes and flip maps, "
                    "computed from the symbolic derivation.",
    )

    def unprocessable(message: str, loc=("body",)) -> JSONResponse:
        return JSONResponse(status_code=422, content={"detail": [{"loc": list(loc), "msg": message, "type": "value_error"}]})

    @app.exception_handler(SkewpendError)
    async def _skewpend_error(request: Request, exc: SkewpendError):
        return unprocessable(str(exc))

    @app.exception_handler(RequestValidationError)
    async def _invalid(request: Request, exc: RequestValidationError):
        # FastAPI's own handler echoes the input, which may be NaN (not JSON) or megabytes: name
        # the field and say what is wrong, nothing else
        detail = [{"loc": [str(x) for x in e.get("loc", ())], "msg": str(e.get("msg", "invalid")),
                   "type": str(e.get("type", "value_error"))} for e in exc.errors()]
        return JSONResponse(status_code=422, content={"detail": detail})

    @app.exception_handler(StarletteHTTPException)
    async def _http(request: Request, exc: StarletteHTTPException):
        if exc.status_code == 400:  # a body that is not UTF-8 JSON: bad input like any other
            return unprocessable("the request body must be JSON (UTF-8)")
        return JSONResponse(status_code=exc.status_code, content={"detail": exc.detail}, headers=exc.headers)

    app.state.stopping = stopping
    app.add_middleware(_Guard, hosts=None if hosts is None else frozenset(hosts), port=port)

    async def heavy(fn):
        """``fn(check)`` in a worker thread, at most HEAVY_SLOTS at a time, within TIME_LIMIT s
        (waiting for a slot included).  ``check()`` raises once the time is up: the work calls it
        between its bounded steps (the library's progress callbacks), so a request answered 503
        stops computing and frees its slot within a fraction of a second."""
        cancel = threading.Event()

        def check(*_):
            if cancel.is_set() or stopping.is_set():
                raise _Deadline()

        def run():
            while not slots.acquire(timeout=0.05):
                check()
            try:
                return fn(check)
            finally:
                slots.release()

        try:
            return await asyncio.wait_for(run_in_threadpool(run), timeout=TIME_LIMIT)
        except (asyncio.TimeoutError, _Deadline):
            cancel.set()
            if stopping.is_set():
                raise HTTPException(status_code=503, detail="the server is shutting down") from None
            raise HTTPException(status_code=503, detail=f"the computation took longer than {TIME_LIMIT:g} s") from None
        except BaseException:  # cancelled (the client left, the server stops): the work stops too
            cancel.set()
            raise

    # -- the page ---------------------------------------------------------------------------------------
    @app.get("/", include_in_schema=False)
    async def index():
        return FileResponse(_WEB / "index.html", media_type="text/html")

    @app.get("/physics.js", include_in_schema=False)
    async def physics_js():
        return Response(physics, media_type="text/javascript", headers={"Cache-Control": "no-cache"})

    @app.get("/sources/{name}.js", include_in_schema=False)
    async def source(name: str):
        if name not in registrations:
            raise StarletteHTTPException(status_code=404)
        return Response(registrations[name], media_type="text/javascript", headers={"Cache-Control": "no-cache"})

    app.mount("/static/katex", StaticFiles(directory=str(katex_dir())), name="katex")
    app.mount("/static", StaticFiles(directory=str(_WEB)), name="static")

    # -- the API ----------------------------------------------------------------------------------------
    @app.get("/api/version", summary="skewpend's version and the request limits")
    async def version() -> Dict[str, Any]:
        return {"skewpend": __version__, "limits": LIMITS, "time_limit": TIME_LIMIT}

    @app.post("/api/equations", responses=_ERRORS, summary="The equations of motion M(q) q'' = f(q, q') for the given parameters (LaTeX)")
    async def equations(req: EquationsRequest) -> Dict[str, Any]:
        values = tuple((k, float(v)) for k, v in req.model.model_dump().items())
        _params(req.model)  # validated by the library first (one clear message)
        return await heavy(lambda check: _equations(values, req.digits))

    @app.post("/api/simulate", responses=_ERRORS, summary="A trajectory by DOP853 (compiled code generated from the derivation)")
    async def simulate(req: SimulateRequest) -> Dict[str, Any]:
        points = req.t_end / req.dt_out + 1
        if points > LIMITS["simulate_points"]:
            return unprocessable(f"t_end / dt_out + 1 = {points:.6g} output points is more than the limit "
                                 f"{LIMITS['simulate_points']}; use a larger dt_out", ("body", "dt_out"))
        params = _params(req.model)

        def run(check):
            from ..numeric.simulation import simulate as sim

            tr = sim(params, req.y0, req.t_end, dt_out=req.dt_out, method="dop853", rtol=req.rtol, atol=req.atol,
                     max_steps=LIMITS["simulate_steps"], progress=check)
            return {"t": _finite(tr.t), "y": _finite(tr.y), "energy": _finite(tr.energy),
                    "status": tr.status, "message": tr.message, "steps": int(tr.stats.get("steps", 0))}

        return await heavy(run)

    @app.post("/api/modes", responses=_ERRORS, summary="Normal modes about the hanging position")
    async def modes(req: ModesRequest) -> Dict[str, Any]:
        params = _params(req.model)

        def run(check):
            from ..analysis.modes import normal_modes

            m = normal_modes(params)
            return {"frequencies": _finite(m.frequencies), "frequencies_hz": _finite(m.frequencies / (2 * math.pi)),
                    "periods": _finite(m.periods), "shapes": _finite(m.shapes), "ratios": _finite(m.ratios),
                    "damping_ratios": _finite(m.damping_ratios)}

        return await heavy(run)

    @app.post("/api/flipmap", responses=_ERRORS, summary="A small flip-time map of starts at rest")
    async def flipmap(req: FlipMapRequest) -> Dict[str, Any]:
        work = req.n * req.n * req.t_end
        if work > LIMITS["flipmap_cells_time"]:
            return unprocessable(f"n^2 x t_end = {work:.6g} cell-seconds is more than the limit "
                                 f"{LIMITS['flipmap_cells_time']:g}; use a smaller n or t_end", ("body", "n"))
        params = _params(req.model)

        def run(check):
            import warnings

            from ..analysis.flipmap import flip_map

            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # failed cells are counted in the answer
                # a row per chunk, the deadline checked after each; each cell at most FLIP_CELL_STEPS steps
                fm = flip_map(params, req.n, t_end=req.t_end, workers=1, chunk_size=req.n, progress=check,
                              max_steps=LIMITS["flipmap_cell_steps"])
            return {"n": req.n, "t_end": req.t_end, "phi0": _finite(fm.phi0[:, 0]), "psi0": _finite(fm.psi0[0]),
                    "flip_time": _finite(fm.flip_time), "which": fm.which.astype(int).tolist(),
                    "failed": int(fm.stats["failed"]), "wall_time": fm.stats["wall_time"]}

        return await heavy(run)

    return app


class Address:
    """Where :func:`serve` listens: ``host`` (an IP address without brackets or a host name),
    ``port``, ``url`` (IPv6 in brackets; a wildcard address shown as 127.0.0.1), ``loopback``
    (this machine only) and ``warning`` (a sentence for a front end to show when it is not)."""

    def __init__(self, host: str, port: int) -> None:
        self.host, self.port = host, port
        self.loopback = _is_loopback(host)
        shown = "127.0.0.1" if host in ("0.0.0.0", "::") else (f"[{host}]" if ":" in host else host)
        self.url = f"http://{shown}:{port}/"
        self.warning = None if self.loopback else (
            f"serving on {host}:{port}, not only on this machine: anyone who can reach it can use the explorer "
            "(its work per request is bounded)")

    def __repr__(self) -> str:
        return f"Address({self.host!r}, {self.port})"


def check_host(host) -> str:
    """``host`` as :func:`serve` binds it: an IP address (``::1`` or ``[::1]`` -> ``::1``) or a
    host name (ASCII letters, digits, ``.`` and ``-``); :class:`ParameterError` otherwise."""
    import ipaddress
    import re

    from ..errors import ParameterError

    name = host.strip() if isinstance(host, str) else ""
    bare = name[1:-1] if name.startswith("[") and name.endswith("]") else name
    with suppress(ValueError):
        return str(ipaddress.ip_address(bare))
    if not (name and name.isascii() and re.fullmatch(r"[A-Za-z0-9](?:[A-Za-z0-9.-]{0,251}[A-Za-z0-9])?", name)):
        raise ParameterError(f"host: expected an IP address or a host name, got {host!r}", parameter="host")
    return name.lower()


def _check_port(port) -> int:
    from ..errors import ParameterError

    if isinstance(port, str) and port.strip().isascii() and port.strip().isdigit() and len(port.strip()) <= 5:
        port = int(port.strip())
    if isinstance(port, bool) or not isinstance(port, int) or not 0 <= port <= 65535:
        raise ParameterError(f"port: expected a whole number from 1 to 65535 (0: any free port), got {port!r}",
                             parameter="port")
    return port


def _is_loopback(host: str) -> bool:
    import ipaddress

    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return host == "localhost"


def _bind(host: str, port: int):
    """The listening sockets of ``host:port`` (every address of a name such as ``localhost``,
    on one port), or one :class:`ParameterError` naming the address."""
    import socket

    from ..errors import ParameterError

    try:
        infos = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM, flags=socket.AI_PASSIVE)
    except (OSError, UnicodeError) as exc:
        raise ParameterError(f"host: cannot listen on {host!r}: {getattr(exc, 'strerror', None) or exc}",
                             parameter="host") from None
    sockets, seen = [], set()
    try:
        for family, kind, proto, _, address in infos:
            if (family, address[0]) in seen or family not in (socket.AF_INET, socket.AF_INET6):
                continue
            seen.add((family, address[0]))
            sock = socket.socket(family, kind, proto)
            sockets.append(sock)
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            if family == socket.AF_INET6 and len(infos) > 1:
                sock.setsockopt(socket.IPPROTO_IPV6, socket.IPV6_V6ONLY, 1)
            try:
                sock.bind((address[0], port, *address[2:]))
            except OSError as exc:
                import errno

                shown = f"[{address[0]}]" if family == socket.AF_INET6 else address[0]
                if exc.errno == errno.EADDRNOTAVAIL:  # not an address of this machine
                    raise ParameterError(f"host: cannot listen on {shown}: {exc.strerror or exc}; use an address of "
                                         "this machine (e.g. 127.0.0.1 or 0.0.0.0)", parameter="host") from None
                raise ParameterError(f"port: cannot listen on {shown}:{port}: {exc.strerror or exc}; choose another "
                                     "port or host", parameter="port") from None
            port = port or sock.getsockname()[1]  # port 0: the rest of the addresses on the one chosen
        if not sockets:
            raise ParameterError(f"host: {host!r} has no IP address to listen on", parameter="host")
    except BaseException:
        for sock in sockets:
            sock.close()
        raise
    return sockets


def check_address(host="127.0.0.1", port=8000) -> Address:
    """The :class:`Address` :func:`serve` would listen on, checked: the host is valid and the port
    can be bound now (tried and released); :class:`ParameterError` naming ``host`` or ``port``."""
    host, port = check_host(host), _check_port(port)
    sockets = _bind(host, port)
    try:
        return Address(host, sockets[0].getsockname()[1])
    finally:
        for sock in sockets:
            sock.close()


def _allowed_hosts(host: str) -> frozenset:
    """The names the Host header may give for a server bound to ``host``."""
    import socket

    names = {host}
    if _is_loopback(host):
        names |= {"localhost", "127.0.0.1", "::1"}
    if host in ("0.0.0.0", "::"):  # every interface: any IP address, and this machine's names
        names |= {"localhost", "*ip", socket.gethostname().lower(), socket.getfqdn().lower()}
    return frozenset(names)


def _protocol():
    """uvicorn's h11 protocol with a deadline for a request's headers: a connection that has not
    sent complete headers within HEADER_TIMEOUT s after connecting (or after its last answer) is
    closed -- uvicorn's keep-alive timer is reset by every byte, so a slow client could hold it forever."""
    from uvicorn.protocols.http.h11_impl import H11Protocol

    class Protocol(H11Protocol):
        _header_timer = None
        _partial = False

        def _arm(self) -> None:
            self._disarm()
            self._partial = False
            self._header_timer = self.loop.call_later(HEADER_TIMEOUT, self._header_timeout)

        def _disarm(self) -> None:
            if self._header_timer is not None:
                self._header_timer.cancel()
                self._header_timer = None

        def _header_timeout(self) -> None:
            self._header_timer = None
            if not self.transport.is_closing():
                if self._partial:
                    self.transport.write(b"HTTP/1.1 408 Request Timeout\r\ncontent-length: 0\r\nconnection: close\r\n\r\n")
                self.transport.close()

        def connection_made(self, transport) -> None:
            super().connection_made(transport)
            self._arm()

        def data_received(self, data: bytes) -> None:
            cycle = self.cycle
            self._partial = True
            super().data_received(data)
            if self.cycle is not cycle:  # the headers of a request are complete
                self._disarm()

        def on_response_complete(self) -> None:
            cycle = self.cycle
            super().on_response_complete()
            if self.cycle is cycle and not self.transport.is_closing():  # waiting for the next request
                self._arm()

        def connection_lost(self, exc) -> None:
            self._disarm()
            super().connection_lost(exc)

    return Protocol


def serve(host: str = "127.0.0.1", port: int = 8000, *, open_browser: bool = False, log_level: str = "warning",
          ready=None, stop=None, physics_params=None) -> None:
    """Run the explorer with uvicorn on ``host:port`` (:func:`check_address`; port 0: any free port) until
    Ctrl-C or SIGTERM; a bad or unbindable address is one :class:`ParameterError`, raised before anything starts.

    ``ready``: called with the :class:`Address` once listening; ``open_browser``: open the page then.
    ``stop``: a :class:`threading.Event` that stops the server as Ctrl-C does (for a server run in a thread).
    ``physics_params``: as for :func:`create_app`.  At the signal, in-flight computations are cancelled
    (answered 503) and the server stops within about :data:`SHUTDOWN_GRACE` s; the signal is then raised
    again by uvicorn (a :class:`KeyboardInterrupt` for Ctrl-C)."""
    require_web()
    import uvicorn

    host, port = check_host(host), _check_port(port)
    sockets = _bind(host, port)
    try:
        address = Address(host, sockets[0].getsockname()[1])
        app = create_app(physics_params=physics_params, hosts=_allowed_hosts(host), port=address.port)
        stopping = app.state.stopping

        class Server(uvicorn.Server):
            def handle_exit(self, sig, frame) -> None:
                stopping.set()  # the work in flight stops at its next check (a fraction of a second)
                super().handle_exit(sig, frame)

            async def startup(self, sockets=None) -> None:
                await super().startup(sockets)
                if self.started:
                    if ready is not None:
                        ready(address)
                    if open_browser:
                        import webbrowser

                        threading.Thread(target=webbrowser.open, args=(address.url,), daemon=True).start()

            async def on_tick(self, counter: int) -> bool:
                if stop is not None and stop.is_set():
                    stopping.set()
                    self.should_exit = True
                return await super().on_tick(counter)

            async def shutdown(self, sockets=None) -> None:
                stopping.set()
                await super().shutdown(sockets)

        config = uvicorn.Config(
            app, host=host, port=address.port, log_level=log_level, http=_protocol(), lifespan="off",
            timeout_keep_alive=int(math.ceil(HEADER_TIMEOUT)), limit_concurrency=MAX_CONNECTIONS,
            timeout_graceful_shutdown=int(math.ceil(SHUTDOWN_GRACE)), h11_max_incomplete_event_size=16 * 1024)
        Server(config).run(sockets=sockets)
    finally:
        for sock in sockets:
            sock.close()
