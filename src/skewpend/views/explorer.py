"""The live explorer: a local web app over the library (``skewpend serve``; the ``web`` extra).

The page (``web/index.html``, ``web/app.js``) draws the moving pendulum in 3D with three.js --
bundled in the package from the npm ``three`` package, never loaded from a CDN -- and integrates
the motion in the browser with the JavaScript *generated from the derivation*
(:func:`skewpend.numeric.codegen.explorer_js`, printed when the app is created and served as
``/physics.js``; the sliders change the parameter vector, never the code).  Heavier work goes
through a JSON API, documented by its OpenAPI schema (``/openapi.json``, ``/docs``):

* ``POST /api/equations`` -- the equations of motion for the current parameters (LaTeX);
* ``POST /api/simulate`` -- a trajectory (DOP853, compiled), with the energy;
* ``POST /api/modes`` -- the normal modes (frequencies, shapes);
* ``POST /api/flipmap`` -- a small flip-time map (a click on a cell starts the 3D motion there).

Safety: the server binds 127.0.0.1 unless told otherwise; every request is validated (bad input
-> HTTP 422 with a message naming the field); the work a request may ask for is bounded (grid
size, duration, output points: :data:`LIMITS`) and larger requests are refused at once with 422;
heavy work runs in worker threads, at most :data:`HEAVY_SLOTS` at a time, each with a time limit
(:data:`TIME_LIMIT` s, then HTTP 503).  Bad parameters found by the library (e.g. an inertia that
is not physical) are 422 too, with the library's one-line message.
"""

import asyncio
import math
import threading
from functools import lru_cache
from importlib import resources
from pathlib import Path
from typing import Any, Dict, List

from .. import __version__
from ..errors import SkewpendError

__all__ = ["create_app", "LIMITS", "TIME_LIMIT", "HEAVY_SLOTS", "require_web", "WEB_EXTRA"]

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
_WEB = Path(__file__).resolve().parent / "web"


#: The error answers of the API (besides FastAPI's own 422 for invalid requests).
_ERRORS = {422: {"description": "invalid input: detail names the field and what is allowed"},
           503: {"description": "the computation took longer than the time limit"}}


class _Deadline(Exception):
    """Raised in a worker thread whose request ran out of time."""


def require_web(what: str = "the explorer"):
    """FastAPI and uvicorn, or one clear :class:`SkewpendError` naming the extra to install."""
    try:
        import fastapi  # noqa: F401
        import uvicorn  # noqa: F401
    except ImportError:
        raise SkewpendError(f"{what} needs FastAPI and uvicorn, which are not installed: {WEB_EXTRA}") from None


def _models():
    """The request models (pydantic), built on first use so that importing this module is cheap."""
    from typing import Annotated

    from pydantic import BaseModel, ConfigDict, Field

    two_pi = 2 * math.pi
    Entry = Annotated[float, Field(ge=-1000, le=1000)]

    class Model(BaseModel):
        """The pendulum: thin uniform rods with the specification's hinge axes (SI units, radians)."""

        model_config = ConfigDict(extra="forbid", allow_inf_nan=False, strict=True)
        a: float = Field(1.0, gt=0, le=10, description="length of rod 1 [m]")
        b: float = Field(0.8, gt=0, le=10, description="length of rod 2 [m]")
        m1: float = Field(1.0, gt=0, le=100, description="mass of rod 1 [kg]")
        m2: float = Field(0.7, gt=0, le=100, description="mass of rod 2 [kg]")
        alpha: float = Field(0.6, ge=-two_pi, le=two_pi, description="skew angle of the hinges [rad]")
        g: float = Field(9.81, ge=0, le=100, description="gravitational acceleration [m/s^2]")
        c1: float = Field(0.0, ge=0, le=100, description="damping of hinge 1 [N m s]")
        c2: float = Field(0.0, ge=0, le=100, description="damping of hinge 2 [N m s]")
        tau1: float = Field(0.0, ge=-1000, le=1000, description="constant torque at hinge 1 [N m]")
        tau2: float = Field(0.0, ge=-1000, le=1000, description="constant torque at hinge 2 [N m]")

    class EquationsRequest(BaseModel):
        model_config = ConfigDict(extra="forbid", allow_inf_nan=False, strict=True)
        model: Model = Field(default_factory=Model)
        digits: int = Field(4, ge=2, le=8, description="significant digits of the numbers shown")

    class SimulateRequest(BaseModel):
        model_config = ConfigDict(extra="forbid", allow_inf_nan=False, strict=True)
        model: Model = Field(default_factory=Model)
        y0: List[Entry] = Field([1.2, -0.8, 0.0, 0.0], min_length=4, max_length=4,
                                description="initial state (phi, psi, dphi, dpsi) [rad, rad/s], each at most 1000")
        t_end: float = Field(10.0, gt=0, le=LIMITS["simulate_t_end"], description="length [s]")
        dt_out: float = Field(0.01, gt=0, le=LIMITS["simulate_t_end"], description="output interval [s]")
        rtol: float = Field(1e-10, ge=1e-14, le=1e-3, description="relative tolerance of DOP853")

    class ModesRequest(BaseModel):
        model_config = ConfigDict(extra="forbid", allow_inf_nan=False, strict=True)
        model: Model = Field(default_factory=Model)

    class FlipMapRequest(BaseModel):
        model_config = ConfigDict(extra="forbid", allow_inf_nan=False, strict=True)
        model: Model = Field(default_factory=Model)
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
    out = arr.tolist()

    def clean(x):
        if isinstance(x, list):
            return [clean(v) for v in x]
        return x if math.isfinite(x) else None

    return clean(out)


@lru_cache(maxsize=256)
def _equations(values: tuple, digits: int) -> Dict[str, Any]:
    from ..symbolic.derivation import derive
    from ..symbolic.model import Parameters
    from ..symbolic.layout import equations_tex, numeric
    from ..symbolic.render import tex

    names = ("a", "b", "m1", "m2", "alpha", "g", "c1", "c2", "tau1", "tau2")
    params = Parameters(**dict(zip(names, values)))
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


def create_app(*, physics_params=None):
    """The FastAPI application.  ``physics_params``: the bodies and axes whose generated
    JavaScript the page integrates (default: the specification's thin rods)."""
    require_web()
    from fastapi import FastAPI, HTTPException, Request
    from fastapi.exceptions import RequestValidationError
    from fastapi.responses import FileResponse, JSONResponse, Response
    from starlette.exceptions import HTTPException as StarletteHTTPException
    from fastapi.staticfiles import StaticFiles
    from starlette.concurrency import run_in_threadpool

    from ..numeric.codegen import explorer_js
    from ..symbolic.model import Parameters

    _, EquationsRequest, SimulateRequest, ModesRequest, FlipMapRequest = _models()
    physics = explorer_js(physics_params if physics_params is not None else Parameters())
    slots = threading.BoundedSemaphore(HEAVY_SLOTS)

    app = FastAPI(
        title="skewpend explorer",
        version=__version__,
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

    @app.middleware("http")
    async def _body_size(request: Request, call_next):
        size = request.headers.get("content-length")
        if size is not None and (not size.isdigit() or int(size) > MAX_BODY):
            return unprocessable(f"the request body must be at most {MAX_BODY} bytes")
        return await call_next(request)

    async def heavy(fn):
        """``fn(check)`` in a worker thread, at most HEAVY_SLOTS at a time, within TIME_LIMIT s
        (waiting for a slot included).  ``check()`` raises once the time is up: the work calls it
        between its bounded steps (the library's progress callbacks), so a request answered 503
        stops computing and frees its slot within a fraction of a second."""
        cancel = threading.Event()

        def check(*_):
            if cancel.is_set():
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
            raise HTTPException(status_code=503, detail=f"the computation took longer than {TIME_LIMIT:g} s") from None

    # -- the page ---------------------------------------------------------------------------------------
    @app.get("/", include_in_schema=False)
    async def index():
        return FileResponse(_WEB / "index.html", media_type="text/html")

    @app.get("/physics.js", include_in_schema=False)
    async def physics_js():
        return Response(physics, media_type="text/javascript", headers={"Cache-Control": "no-cache"})

    app.mount("/static/katex", StaticFiles(directory=str(_katex_dir())), name="katex")
    app.mount("/static", StaticFiles(directory=str(_WEB)), name="static")

    # -- the API ----------------------------------------------------------------------------------------
    @app.get("/api/version", summary="skewpend's version and the request limits")
    async def version() -> Dict[str, Any]:
        return {"skewpend": __version__, "limits": LIMITS, "time_limit": TIME_LIMIT}

    @app.post("/api/equations", responses=_ERRORS, summary="The equations of motion M(q) q'' = f(q, q') for the given parameters (LaTeX)")
    async def equations(req: EquationsRequest) -> Dict[str, Any]:
        values = tuple(float(v) for v in req.model.model_dump().values())
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

            tr = sim(params, req.y0, req.t_end, dt_out=req.dt_out, rtol=req.rtol, atol=req.rtol,
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


def _katex_dir() -> Path:
    return Path(str(resources.files("skewpend.views").joinpath("assets", "katex")))


def serve(host: str = "127.0.0.1", port: int = 8000, *, open_browser: bool = False, log_level: str = "warning") -> None:
    """Run the explorer with uvicorn until Ctrl-C."""
    require_web()
    import uvicorn

    app = create_app()
    if open_browser:
        import webbrowser

        shown = "127.0.0.1" if host in ("0.0.0.0", "::") else host
        threading.Timer(1.0, webbrowser.open, args=(f"http://{shown}:{port}/",)).start()
    uvicorn.run(app, host=host, port=port, log_level=log_level)
