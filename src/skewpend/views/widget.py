"""skewpend in a notebook cell: the live 3D pendulum with its sliders, as an `anywidget
<https://anywidget.dev>`_ widget (JupyterLab, Jupyter Notebook 7, VS Code, Colab).

In a notebook cell::

    w = skewpend.widget()                      # the cell's last line shows it; drag to turn
    w.params = w.params.replace(alpha=0.3)     # the view follows
    w.y0 = (2.0, 0.0, 0.0, 0.0)                # and starts again from there
    w.state.t, w.state.y                       # what the view shows now
    tr = w.run(20.0)                           # skewpend.simulate computes; the view replays it
    skewpend.widget(chain)                     # a chain of links: its n rods, q0 a joint, g and damping

Any model gets the same view; what its sliders set follows the form of the page's physics
(:func:`~skewpend.numeric.explorer_source.page_form`, as the explorer's page): the double pendulum's
parameters -- a chain of two with the specification's axes among them -- every scalar; a longer chain, or a
model with Coulomb friction or rotors (the JavaScript printed from the recursive algorithms' graphs,
:func:`~skewpend.numeric.recursive.chain_code`) each joint's start angle, ``g`` and each joint's damping (its
bodies and axes are fixed at creation, as the double pendulum's), ``y0 = (q1 … qn, dq1 … dqn)``.

The view is the same front end as the explorer's and the report's (``web/scene.js``); its live
motion is the JavaScript generated from the derivation for these bodies and axes, advanced by
RK4, and ``run`` replays the states the compiled integrator computed.  State is synced both
ways: a slider moved in the cell changes ``w.params`` or ``w.y0``; Python's changes move the
sliders.  Needs the ``notebook`` extra (``pip install 'skewpend[notebook]'``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Optional, Sequence, Tuple

import numpy as np

try:
    import anywidget
    import traitlets
except ImportError as exc:  # pragma: no cover - the extra is part of the test install
    raise ImportError("skewpend.widget needs anywidget: pip install 'skewpend[notebook]'") from exc

from .. import schema
from ..errors import ParameterError
from ..symbolic.model import SCALAR_NAMES, Parameters
from .frontend import page_sliders

__all__ = ["widget", "PendulumWidget", "WidgetState"]

#: Frames per second of a replayed run, and the most frames one replay may hold (JSON to the browser).
FPS = 30
MAX_FRAMES = 20_000
#: The sliders shown, in this order (alpha only when the second axis is e0(alpha)).
SLIDERS = ("alpha", "phi0", "psi0") + schema.LENGTH_NAMES + schema.MASS_NAMES + ("g",) + schema.DAMPING_NAMES


@dataclass(frozen=True, eq=False)  # y is an array: compare fields
class WidgetState:
    """What the widget's view shows (as it last reported, about every 0.25 s while it moves):
    ``t`` [s], ``y = (phi, psi, dphi, dpsi)``, ``mode`` (``"live"``: the browser integrates;
    ``"replay"``: a computed run, at ``frame``), ``ok`` (False once the live motion became
    non-finite) and ``message``.  Before any view reported: ``mode == "not shown"``."""

    t: float
    y: np.ndarray
    mode: str
    frame: Optional[int] = None
    ok: bool = True
    message: str = ""


class WidgetValueError(ParameterError, traitlets.TraitError):
    """A refused value of a synced trait: a :class:`~skewpend.ParameterError` that traitlets
    also knows as its own (it then rolls back the change's other traits)."""


def chain_slider_values(chain) -> dict:
    """What a chain's sliders change, at the chain's values: ``g`` and each joint's damping ``c<k>``."""
    return {"g": float(chain.g), **{f"c{link.index}": float(link.damping) for link in chain.links}}


def _zeroed(chain):
    """``chain`` with its sliders at a fixed reference (no damping, g = 9.81): its bodies and axes alone."""
    return chain_with(chain, {k: 0.0 for k in chain_slider_values(chain)} | {"g": 9.81})


def chain_with(chain, values: dict):
    """``chain`` with the sliders' ``values`` (``g``, ``c<k>``) applied, validated by the chain itself."""
    from dataclasses import replace

    out = replace(chain, g=values["g"])
    for link in chain.links:
        out = out.replace_link(link.index, damping=values[f"c{link.index}"])
    return out


def _front_end(geometry) -> Tuple[str, str]:
    from .frontend import WEB_DIR, WIDGET_ORDER, module_bundle

    return module_bundle(WIDGET_ORDER, "widget", geometry), (WEB_DIR / "widget.css").read_text(encoding="utf-8")


class PendulumWidget(anywidget.AnyWidget):
    """The live 3D pendulum in a notebook; make it with :func:`skewpend.widget`.

    Synced with the view: ``params`` (the scalars; the bodies and axes are fixed at creation),
    ``y0``, ``running``; the view writes back what it shows (:attr:`state`).  :meth:`run`
    replays a run computed by :func:`skewpend.simulate`; :meth:`restart`, :meth:`play`,
    :meth:`pause` do what their buttons do."""

    # the model's state, synced with the view (widget.js)
    values = traitlets.Dict().tag(sync=True)
    y0 = traitlets.Any([0.0, 0.0, 0.0, 0.0]).tag(sync=True)  # any 4 numbers in; a list of floats kept
    running = traitlets.Bool(True).tag(sync=True)
    replay = traitlets.Dict().tag(sync=True)
    sliders = traitlets.List(traitlets.Unicode()).tag(sync=True)
    height = traitlets.Int(420).tag(sync=True)
    shown = traitlets.Dict().tag(sync=True)
    specs = traitlets.List().tag(sync=True)  # the sliders (frontend.page_sliders: one definition for every model)
    size = traitlets.Float(0.0).tag(sync=True)  # a chain's length scale [m] (the double pendulum's: from a, b)
    reach = traitlets.Float(0.0).tag(sync=True)  # a chain's drawn reach [m] (views.drawing.drawn_reach; 0: none)
    frame = traitlets.List().tag(sync=True)  # [centre, radius] where hinge 1 is off the roof (drawing.drawn_frame; []: none)

    def __init__(self, params: Optional[Parameters] = None, y0: Optional[Sequence[float]] = None, *,
                 height: int = 420) -> None:
        from .. import checks
        from ..config import reference_parameters, reference_state
        from ..numeric.conventions import geometry_of
        from ..numeric.explorer_source import page_form

        height = checks.whole("height", height, 160, 4000, what="the view's height in pixels")
        if params is not None and not hasattr(params, "as_chain"):
            raise ParameterError(checks.not_parameters(params, "the widget"))
        # the page's form decides what its sliders set (explorer_source.page_form): the exact form every scalar of
        # the double pendulum's parameters, the recursive algorithms' g and each joint's damping (bodies fixed)
        form, printed = page_form(params) if params is not None and params.is_numeric else ("exact", None)
        self._chain = printed if form == "recursive" else None
        if self._chain is not None:  # the recursive form: the bodies and axes fixed, g and damping its sliders
            from ..config import CHAIN_Q0
            from .drawing import drawn_frame, drawn_reach

            params = self._chain
            shape = self._geometry = _zeroed(params)
            self._esm, self._css = _front_end(shape)
            n = params.n
            specs = page_sliders(params)
            super().__init__(values=chain_slider_values(params),
                             y0=self._start((CHAIN_Q0,) * n + (0.0,) * n if y0 is None else y0),
                             sliders=[spec[0] for spec in specs[-n:] + specs[:-n]], specs=specs,  # the starts first
                             size=max(link.length for link in params.links), reach=drawn_reach(params),
                             frame=list(drawn_frame(params) or []), height=height)
            return
        params = reference_parameters() if params is None else checks.numeric_params(params, "the widget")
        geometry = geometry_of(params)
        self._geometry = geometry
        self._esm, self._css = _front_end(geometry)
        names = [n for n in SCALAR_NAMES if n != "alpha" or geometry.uses_alpha]
        super().__init__(values={n: float(getattr(params, n)) for n in names},
                         y0=self._start(reference_state() if y0 is None else y0),
                         sliders=[n for n in SLIDERS if n in names or n in ("phi0", "psi0")],
                         specs=page_sliders(geometry), height=height)

    # -- validation of every change (from Python or from the view) ----------------------------------
    @traitlets.validate("values")
    def _valid_values(self, proposal: Any) -> dict:
        try:
            return self._checked_values(proposal["value"])
        except ParameterError as exc:
            raise WidgetValueError(str(exc)) from None

    def _checked_values(self, given: Any) -> dict:
        values = dict(given)
        chain = self._chain
        allowed = (list(chain_slider_values(chain)) if chain is not None else
                   [n for n in SCALAR_NAMES if n != "alpha" or self._geometry.uses_alpha])
        unknown = sorted(set(values) - set(allowed))
        missing = [n for n in allowed if n not in values]
        if unknown or missing:
            what = "; ".join(([f"unknown {', '.join(unknown)}"] if unknown else []) +
                             ([f"missing {', '.join(missing)}"] if missing else []))
            raise ParameterError(f"widget values: {what}; expected all of {', '.join(allowed)} (set w.params to change some)")
        if chain is not None:
            return chain_slider_values(chain_with(chain, values))  # checks each value (damping >= 0, ...)
        params = self._geometry.replace(**values)  # checks each value (positive masses, ...)
        return {n: float(getattr(params, n)) for n in allowed}

    @traitlets.validate("y0")
    def _valid_y0(self, proposal: Any) -> list:
        try:
            return self._start(proposal["value"])
        except ParameterError as exc:
            raise WidgetValueError(str(exc)) from None

    @traitlets.validate("shown")
    def _valid_shown(self, proposal: Any) -> dict:
        """What a view reports: a time, a state of 4 numbers (a chain's 2 n), a mode (or nothing yet)."""
        shown = dict(proposal["value"])
        if not shown:
            return shown
        size = 2 * self._geometry.n
        try:
            t, y = float(shown["t"]), [float(v) for v in shown["y"]]
            ok = len(y) == size and shown.get("mode") in ("live", "replay") and math.isfinite(t)
        except (KeyError, TypeError, ValueError):
            ok = False
        if not ok:
            raise WidgetValueError(f"a view's report must hold t, y ({size} numbers) and mode (live or replay), "
                                   f"got {shown!r}")
        return shown

    @traitlets.observe("values", "y0")
    def _drop_replay(self, change: Any) -> None:
        """A replayed run belongs to the parameters and start it was computed from."""
        if self.replay and change["old"] != change["new"]:
            self.replay = {}

    def set_state(self, sync_data: dict) -> None:
        """A view's change (ipywidgets calls this).  One that the checks refuse -- no slider makes
        one, but a view is another program -- is logged in one line and the view is sent the
        values kept, so the view and Python never disagree."""
        try:
            super().set_state(sync_data)
        except traitlets.TraitError as exc:
            self.log.warning("skewpend widget: a change from the view was refused: %s", exc)
            self.send_state(list(sync_data))

    # -- the public face ------------------------------------------------------------------------------
    @property
    def params(self) -> Parameters:
        """The pendulum shown: the bodies and axes given at creation with the current scalars (a chain's: with
        the current ``g`` and damping)."""
        if self._chain is not None:
            return chain_with(self._chain, self.values)
        return self._geometry.replace(**self.values)

    @params.setter
    def params(self, params: Parameters) -> None:
        from .. import checks
        from ..numeric.conventions import geometry_of

        if self._chain is not None:
            chain = self._same_body(params)
            if chain is None:
                raise ParameterError("the widget's chain is fixed when it is made (its physics is generated for its "
                                     "bodies and axes); change g and the damping only, or make a new skewpend.widget")
            self.values = chain_slider_values(chain)
            return
        checks.numeric_params(params, "the widget")
        if geometry_of(params) != self._geometry:
            raise ParameterError("the widget's bodies and axes are fixed when it is made (its physics is generated for "
                                 "them); change scalars only (params.replace(alpha=...)), or make a new skewpend.widget")
        self.values = {n: float(getattr(params, n)) for n in self.values}

    @property
    def state(self) -> WidgetState:
        """What the view shows now (as last reported; see :class:`WidgetState`)."""
        s = self.shown
        if not s:
            return WidgetState(t=0.0, y=np.array(self.y0, dtype=float), mode="not shown")
        return WidgetState(t=float(s["t"]), y=np.array(s["y"], dtype=float), mode=str(s["mode"]),
                           frame=None if s.get("frame") is None else int(s["frame"]), ok=bool(s.get("ok", True)),
                           message=str(s.get("message", "")))

    def run(self, t_end: float = 10.0, **simulate_options: Any):
        """Compute the motion from ``y0`` over ``[0, t_end]`` with :func:`skewpend.simulate`
        (``simulate_options``: ``method``, ``rtol``, ``atol``, ``dt``, ``max_steps``) and replay
        it in the view, :data:`FPS` frames per second; returns the
        :class:`~skewpend.Trajectory` (its rows are the frames)."""
        from .. import checks
        from ..numeric.simulation import simulate

        t_end = checks.finite_seconds("t_end", t_end, zero=False)
        for option in ("dt_out", "out", "keep", "progress", "controller", "throw"):
            if option in simulate_options:
                raise ParameterError(f"widget.run: {option} cannot be set here (the widget replays every frame, "
                                     f"{FPS} per second); allowed: method, rtol, atol, dt, max_steps")
        frames = math.floor(min(t_end, 2.0 * MAX_FRAMES / FPS) * FPS + 1e-9) + 1  # capped: no overflow at 1e308
        if frames > MAX_FRAMES:
            raise ParameterError(f"widget.run: t_end = {t_end:g} s is more than {MAX_FRAMES} frames at {FPS} per second; at most "
                                 f"{MAX_FRAMES} ({MAX_FRAMES / FPS:g} s) are replayed: simulate longer runs with "
                                 "skewpend.simulate and look at them with skewpend.views")
        dt_out = 1.0 / FPS
        if simulate_options.get("method") in ("rk4", "gauss"):  # fixed steps: frames on whole steps
            given = simulate_options.get("dt")
            step = 1e-3 if given is None else checks.positive("dt", given, cap=t_end)
            dt_out = max(1, round(dt_out / step)) * step
            if dt_out > t_end:
                raise ParameterError(f"widget.run: t_end = {t_end:g} s is shorter than one frame ({dt_out:g} s)")
        trajectory = simulate(self.params, self.y0, t_end, dt_out=dt_out, **simulate_options)
        self.show(trajectory)
        return trajectory

    def show(self, trajectory) -> None:
        """Replay ``trajectory`` (a :class:`~skewpend.Trajectory` of these bodies and axes, e.g.
        from :func:`skewpend.simulate` with ``dt_out``) in the view; its parameters and start
        become the widget's."""
        from ..numeric.conventions import geometry_of
        from ..numeric.simulation import Trajectory
        from .frontend import replay_data

        if not isinstance(trajectory, Trajectory):
            raise ParameterError(f"widget.show: expected a skewpend.Trajectory, got {type(trajectory).__name__}")
        if self._chain is not None:
            if self._same_body(trajectory.params) is None:
                raise ParameterError("widget.show: the trajectory's chain differs from the widget's; "
                                     "make a skewpend.widget(trajectory.params)")
        elif (trajectory.params.exact_model() is None
              or geometry_of(trajectory.params.exact_model()) != self._geometry):
            raise ParameterError("widget.show: the trajectory's bodies and axes differ from the widget's; "
                                 "make a skewpend.widget(trajectory.params)")
        n = len(trajectory.t)
        if n > MAX_FRAMES:
            raise ParameterError(f"widget.show: {n} rows are more than the {MAX_FRAMES} frames replayed; "
                                 "simulate with dt_out (e.g. 1/30 s)")
        if not trajectory.kept:
            raise ParameterError("widget.show: the trajectory kept only its first and last rows (keep=False)")
        data = {**replay_data(trajectory),
                "label": f"skewpend.simulate ({trajectory.method}), t = 0 .. {trajectory.t[-1]:g} s",
                "message": "" if trajectory.ok else f"The run stopped early: {trajectory.message}"}
        with self.hold_sync():
            self.params = trajectory.params
            self.y0 = list(trajectory.y[0])
            self.replay = data
            self.running = True

    def _same_body(self, model):
        """``model`` as a chain if it is the widget's up to its sliders' values (g and each joint's damping), else
        None."""
        if not hasattr(model, "as_chain"):  # not a model
            return None
        chain = model.as_chain()
        return chain if chain.n == self._chain.n and _zeroed(chain) == self._geometry else None

    def _start(self, y0: Sequence[float]) -> list:
        from ..parsing import initial_state

        return [float(v) for v in initial_state(y0, self._geometry.coordinates)]

    def restart(self) -> None:
        """Start the motion again from ``y0`` (a replay: from its first frame)."""
        self.send({"cmd": "restart"})

    def play(self) -> None:
        self.running = True

    def pause(self) -> None:
        self.running = False

    def __repr__(self) -> str:
        if self._chain is not None:
            values = f"a chain of {self._chain.n} links, " + ", ".join(f"{k}={v:g}" for k, v in self.values.items()
                                                                       if k == "g" or v)
        else:
            values = ", ".join(f"{k}={v:g}" for k, v in self.values.items()  # a term off at its default is left out
                               if k in SLIDERS or schema.default(k) is None or v != schema.default(k))
        what = "replaying a computed run" if self.replay else "live"
        y0 = ", ".join(f"{v:g}" for v in self.y0)
        return f"<PendulumWidget {what}, {'running' if self.running else 'paused'}: {values}; y0 = ({y0})>"


def widget(params: Optional[Parameters] = None, y0: Optional[Sequence[float]] = None, *,
           height: int = 420) -> PendulumWidget:
    """The live 3D pendulum in a notebook cell (an anywidget): the bodies and axes of ``params``
    (default: :func:`skewpend.reference_parameters`; or a chain of links, its n rods) from
    ``y0 = (phi, psi, dphi, dpsi)`` (default: :func:`skewpend.reference_state`; a chain's
    ``(q1 … qn, dq1 … dqn)``, default every joint at 0.5 rad, at rest), ``height`` pixels tall.  See
    :class:`PendulumWidget` for what it syncs; needs ``pip install 'skewpend[notebook]'``."""
    return PendulumWidget(params, y0, height=height)
