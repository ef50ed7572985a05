"""3-D animation of a simulated trajectory: MP4 (H.264) or GIF.

Every row of a :class:`skewpend.Trajectory` is one frame, so the frames are exactly the
dense-output states at the frame times ``k * speed / fps`` (make the trajectory with
``skewpend.simulate(params, y0, duration * speed, dt_out=speed / fps)``).

The geometry of a frame comes from the trajectory only -- the rod ends ``tr.tips()`` and the
hinge axes ``tr.axes()`` (``n1`` and ``e = P1 . e0``), both generated from the symbolic
derivation; nothing here recomputes the kinematics.  :func:`frame_scene` returns that
geometry in world coordinates exactly as it is drawn, so it can be checked against the
model and against the projected artists of :class:`FrameRenderer`.

Coordinates: the world basis ``i, j, k`` has ``j`` pointing down.  The plot shows
``(X, Y, Z) = (x, z, -y)`` (a proper rotation: the pendulum hangs down the screen, the first
hinge axis ``k`` is the plot's horizontal ``Y``); see :func:`world_to_plot`.

Rendering is Matplotlib 3-D on an Agg canvas (object-oriented, no pyplot).  The static parts
(title, legend, floor grid, roof, the i, j, k triad) are drawn once; each frame restores that
background and draws only the moving artists.  The view limits are a cube fixed by the reach
``a + b`` about the pivot; the framing shows the sphere of that radius below and beside the
pivot, the floor, and upwards as far as this run's rods and axes go.  MP4 goes through the ffmpeg executable that the ``imageio-ffmpeg``
wheel ships, GIF through Pillow.  The file appears complete or not at all.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Dict, Optional, Sequence, Tuple

import numpy as np

from .. import checks
from ..errors import ParameterError, SkewpendError
from ..io import atomic_path
from .style import parameter_text

__all__ = [
    "animate",
    "frame_scene",
    "FrameScene",
    "FrameRenderer",
    "world_to_plot",
    "plot_to_world",
    "choose_view",
    "check_frame_times",
    "check_output",
    "SUFFIXES",
    "DEFAULT_SIZE",
    "DEFAULT_DPI",
    "DEFAULT_TRAIL",
]

#: Output formats, chosen by the file name's suffix.
SUFFIXES = (".mp4", ".gif")
#: Frame size in pixels (width, height).
DEFAULT_SIZE = (640, 480)
DEFAULT_DPI = 100
#: Length of the fading trail of rod 2's tip, in seconds of motion (simulated time).
DEFAULT_TRAIL = 2.0
#: Smallest frame edge accepted [px]: below it nothing is legible.
MIN_EDGE = 64

#: Half length of each drawn hinge axis, as a fraction of the reach a + b.
AXIS_HALF_LENGTH = 0.30
#: Arrow heads of the hinge axes (length, base radius) and the gap to their labels, fractions of a + b.
HEAD_LENGTH, HEAD_RADIUS, LABEL_GAP = 0.09, 0.028, 0.07
#: Radius of the arc marking the skew angle at the second hinge, a fraction of the axis half length.
ARC_RADIUS = 0.55
#: Rod radius, as a fraction of the reach a + b.
ROD_RADIUS = 0.022
#: Default camera (plot coordinates): elevation and azimuth [deg].  Its line of sight makes 43 deg
#: with the first axis k (the plot's Y), so k shows 68 % of its length, and it is 30 deg above the
#: horizon, so the angle between k and the horizontal e0 opens up (alpha = 90 deg shows as 56 deg)
#: while rod 1's swing plane (x, -y) is seen at a slant of 43 deg from its normal.
DEFAULT_VIEW = (30.0, -58.0)
#: The camera keeps at least this angle [deg] to each hinge axis (else another view is chosen).
MIN_VIEW_ANGLE = 25.0

_COLORS = {
    "rod1": (0.23, 0.43, 0.68),
    "rod2": (0.90, 0.50, 0.13),
    "pin": (0.35, 0.35, 0.38),
    "axis1": (0.05, 0.55, 0.40),
    "axis2": (0.80, 0.08, 0.40),
    "trail": (0.42, 0.24, 0.60),
    "shadow": (0.0, 0.0, 0.0, 0.22),
    "roof": (0.55, 0.55, 0.58),
}
_SIDES = 12  # facets around a rod
_SEGMENTS = 4  # pieces along a rod (keeps the painter's sort right where rods meet)


# --------------------------------------------------------------------------------------------
# coordinates


def world_to_plot(points) -> np.ndarray:
    """World ``(x, y, z)`` (``y`` down) -> plot ``(X, Y, Z) = (x, z, -y)``; shape (..., 3)."""
    p = np.asarray(points, dtype=float)
    return np.stack([p[..., 0], p[..., 2], -p[..., 1]], axis=-1)


def plot_to_world(points) -> np.ndarray:
    """Inverse of :func:`world_to_plot`."""
    p = np.asarray(points, dtype=float)
    return np.stack([p[..., 0], -p[..., 2], p[..., 1]], axis=-1)


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _eye(elev: float, azim: float) -> np.ndarray:
    """Unit vector from the scene towards the camera, plot coordinates (Matplotlib's convention)."""
    el, az = math.radians(elev), math.radians(azim)
    return np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])


def _angle_to_line(v: np.ndarray, d: np.ndarray) -> float:
    """Angle [deg] between the direction ``v`` and the line along ``d`` (0..90)."""
    c = abs(float(np.dot(_unit(v), _unit(d))))
    return math.degrees(math.acos(min(1.0, c)))


def choose_view(n1_world, e_world) -> Tuple[float, float]:
    """Camera ``(elev, azim)`` [deg] that sees neither hinge axis end-on.

    :data:`DEFAULT_VIEW` when it keeps :data:`MIN_VIEW_ANGLE` to both axes (it does for the
    default axes ``k`` and ``e0(alpha)``, any alpha: ``e0`` is horizontal and the camera 30 deg
    above the horizon); otherwise the view nearest to it (elevation 10..50 deg) that maximises
    the smaller of the two angles.
    """
    n1 = world_to_plot(np.asarray(n1_world, dtype=float))
    e = world_to_plot(np.asarray(e_world, dtype=float))

    def score(elev: float, azim: float) -> float:
        eye = _eye(elev, azim)
        return min(_angle_to_line(eye, n1), _angle_to_line(eye, e))

    if score(*DEFAULT_VIEW) >= MIN_VIEW_ANGLE:
        return DEFAULT_VIEW
    best, best_key = DEFAULT_VIEW, None
    for elev in range(10, 51, 5):
        for azim in range(-180, 180, 3):
            s = min(score(elev, azim), 55.0)
            dist = abs(elev - DEFAULT_VIEW[0]) + abs((azim - DEFAULT_VIEW[1] + 180) % 360 - 180)
            key = (round(s, 6), -dist)
            if best_key is None or key > best_key:
                best, best_key = (float(elev), float(azim)), key
    return best


# --------------------------------------------------------------------------------------------
# the scene of one frame (world coordinates)


@dataclass(frozen=True)
class FrameScene:
    """The 3-D geometry of frame ``k`` in WORLD coordinates (``y`` down), as it is drawn.

    * ``rods`` -- (3, 3): the pivot (origin), the end of rod 1 (``tip1``), the end of rod 2;
      rod 1 is drawn from ``rods[0]`` to ``rods[1]``, rod 2 from ``rods[1]`` to ``rods[2]``;
    * ``axis_centers`` -- (2, 3): where the hinge axes are drawn: the origin and ``tip1``;
    * ``axis_directions`` -- (2, 3): unit vectors ``n1`` and ``e = P1 . e0`` (``tr.axes()[k]``);
    * ``axis_half_length`` -- each axis is drawn from ``centre - h d`` to ``centre + h d``
      (:meth:`axis_segment`), the arrow head at the ``+`` end;
    * ``trail`` -- (m, 3): rod 2's tip over the last ``trail`` seconds, oldest first, ending at
      ``rods[2]``; ``trail_alpha`` -- (m - 1,): opacity of each trail segment (fading out);
    * ``skew_arc`` -- (m, 3): the arc at ``tip1`` from the direction ``n1`` (drawn there as a dotted
      reference line, ``centre = tip1``, ``direction = n1``) to ``e``: the skew angle;
    * ``t``, ``phi``, ``psi``, ``energy``, ``work`` -- the readout's values.
    """

    k: int
    t: float
    phi: float
    psi: float
    energy: float
    work: float
    rods: np.ndarray
    axis_centers: np.ndarray
    axis_directions: np.ndarray
    axis_half_length: float
    trail: np.ndarray
    trail_alpha: np.ndarray
    skew_arc: np.ndarray

    def axis_segment(self, i: int) -> np.ndarray:
        """End points (2, 3) of hinge axis ``i`` (0: the roof hinge, 1: the second hinge), world."""
        c, d, h = self.axis_centers[i], self.axis_directions[i], self.axis_half_length
        return np.array([c - h * d, c + h * d])


class _Geometry:
    """Per-row data of a trajectory, computed once: rod ends, hinge axes, reach, trail rows."""

    def __init__(self, tr, trail: float = DEFAULT_TRAIL) -> None:
        if not getattr(tr, "kept", True):
            raise ParameterError("the trajectory kept only its first and last rows (keep=False); animate needs every row")
        t = np.asarray(tr.t, dtype=float)
        if t.ndim != 1 or t.size < 1:
            raise ParameterError("the trajectory has no rows to animate")
        trail = checks.finite_seconds("trail", trail)
        p = tr.params
        self.tr = tr
        self.t = t
        self.y = np.asarray(tr.y, dtype=float)
        self.energy = np.asarray(tr.energy, dtype=float)
        self.work = np.asarray(tr.work, dtype=float)
        self.tips = np.asarray(tr.tips(), dtype=float).reshape(-1, 6)
        self.axes = np.asarray(tr.axes(), dtype=float).reshape(-1, 6)
        if self.tips.shape[0] != t.size or self.axes.shape[0] != t.size:
            raise SkewpendError("the trajectory's rod ends or axes do not match its rows")
        self.reach = float(p.a) + float(p.b)
        self.half = AXIS_HALF_LENGTH * self.reach
        self.trail = trail
        # first row of each frame's trail: the earliest row with t >= t_k - trail
        self.trail_start = np.searchsorted(t, t - trail - 1e-9 * max(trail, 1.0), side="left")

    def _arc(self, centre, n1, e) -> np.ndarray:
        return _arc_points(centre, n1, e, ARC_RADIUS * self.half)

    def scene(self, k: int) -> FrameScene:
        n = self.t.size
        if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or not -n <= k < n:
            raise ParameterError(f"frame index must be a whole number in 0..{n - 1}, got {k!r}")
        k = int(k) % n
        tips = self.tips
        rods = np.array([[0.0, 0.0, 0.0], tips[k, 0:3], tips[k, 3:6]])
        centers = np.array([[0.0, 0.0, 0.0], tips[k, 0:3]])
        dirs = np.array([self.axes[k, 0:3], self.axes[k, 3:6]])
        j0 = int(self.trail_start[k])
        trail = tips[j0 : k + 1, 3:6].copy()
        m = trail.shape[0]
        alpha = np.linspace(0.0, 0.9, m)[1:] if m > 1 else np.zeros(0)
        return FrameScene(
            k=k,
            t=float(self.t[k]),
            phi=float(self.y[k, 0]),
            psi=float(self.y[k, 1]),
            energy=float(self.energy[k]),
            work=float(self.work[k]),
            rods=rods,
            axis_centers=centers,
            axis_directions=dirs,
            axis_half_length=self.half,
            trail=trail,
            trail_alpha=alpha,
            skew_arc=self._arc(tips[k, 0:3], dirs[0], dirs[1]),
        )


def _arc_points(centre: np.ndarray, n1: np.ndarray, e: np.ndarray, radius: float, count: int = 24) -> np.ndarray:
    """Points of the circular arc about ``centre`` from direction ``n1`` to direction ``e``."""
    c = float(np.clip(np.dot(n1, e), -1.0, 1.0))
    perp = e - c * n1
    norm = float(np.linalg.norm(perp))
    if norm < 1e-12:  # parallel axes: no arc
        return np.array([centre + radius * n1])
    m = perp / norm
    ang = np.linspace(0.0, math.acos(c), count)
    return centre + radius * (np.cos(ang)[:, None] * n1 + np.sin(ang)[:, None] * m)


def frame_scene(tr, k: int, *, trail: float = DEFAULT_TRAIL) -> FrameScene:
    """The 3-D geometry of frame ``k`` (row ``k`` of ``tr``) in world coordinates, as drawn.

    ``trail``: seconds of motion the tip's trail covers.  The hinge axes are ``tr.axes()[k]``
    (``n1`` at the origin, ``e = P1 . e0`` at the end of rod 1), the rod ends ``tr.tips()[k]``.
    """
    return _Geometry(tr, trail).scene(k)


# --------------------------------------------------------------------------------------------
# solids: shaded cylinders and cones as quadrilaterals (plot coordinates)


def _frame_about(d: np.ndarray, ref: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    u = np.cross(ref, d)
    if np.linalg.norm(u) < 1e-6:
        u = np.cross(np.array([1.0, 0.0, 0.0]) if abs(d[0]) < 0.9 else np.array([0.0, 1.0, 0.0]), d)
    u = _unit(u)
    return u, np.cross(d, u)


_THETA = np.linspace(0.0, 2.0 * np.pi, _SIDES + 1)
_COS, _SIN = np.cos(_THETA), np.sin(_THETA)
_CMID, _SMID = np.cos(_THETA[:-1] + np.pi / _SIDES), np.sin(_THETA[:-1] + np.pi / _SIDES)


def _cylinder(p: np.ndarray, q: np.ndarray, r: float, ref: np.ndarray, segments: int = _SEGMENTS):
    """Quads (N, 4, 3) and outward normals (N, 3) of a closed cylinder from p to q."""
    axis = q - p
    length = float(np.linalg.norm(axis))
    if length < 1e-12:
        return np.zeros((0, 4, 3)), np.zeros((0, 3))
    d = axis / length
    u, w = _frame_about(d, ref)
    ring = r * (_COS[:, None] * u + _SIN[:, None] * w)  # (S+1, 3)
    s = np.linspace(0.0, 1.0, segments + 1)
    centres = p + s[:, None] * axis  # (G+1, 3)
    a = centres[:-1, None, :] + ring[None, :-1, :]
    b = centres[:-1, None, :] + ring[None, 1:, :]
    c = centres[1:, None, :] + ring[None, 1:, :]
    dd = centres[1:, None, :] + ring[None, :-1, :]
    side = np.stack([a, b, c, dd], axis=2).reshape(-1, 4, 3)
    normals = np.broadcast_to(_CMID[:, None] * u + _SMID[:, None] * w, (segments, _SIDES, 3)).reshape(-1, 3)
    # end caps as a fan of quads (centre, v_i, v_i+1, v_i+2)
    caps, cap_normals = [], []
    for centre, nrm in ((p, -d), (q, d)):
        v = centre + ring
        idx = np.arange(0, _SIDES, 2)
        fan = np.stack([np.broadcast_to(centre, (idx.size, 3)), v[idx], v[idx + 1], v[(idx + 2) % (_SIDES + 1)]], axis=1)
        caps.append(fan)
        cap_normals.append(np.broadcast_to(nrm, (idx.size, 3)))
    return (np.concatenate([side] + caps), np.concatenate([normals] + cap_normals))


def _cone(base: np.ndarray, tip: np.ndarray, r: float):
    """Quads (degenerate: triangles) and normals of a cone (arrow head) plus its base disc."""
    axis = tip - base
    length = float(np.linalg.norm(axis))
    d = axis / length
    u, w = _frame_about(d, np.array([0.0, 0.0, 1.0]))
    ring = base + r * (_COS[:, None] * u + _SIN[:, None] * w)
    tips = np.broadcast_to(tip, (_SIDES, 3))
    quads = np.stack([tips, ring[:-1], ring[1:], tips], axis=1)
    radial = _CMID[:, None] * u + _SMID[:, None] * w
    normals = _unit(radial * length + d * r)
    idx = np.arange(0, _SIDES, 2)
    disc = np.stack([np.broadcast_to(base, (idx.size, 3)), ring[idx], ring[idx + 1], ring[(idx + 2) % (_SIDES + 1)]], axis=1)
    return np.concatenate([quads, disc]), np.concatenate([normals, np.broadcast_to(-d, (idx.size, 3))])


# --------------------------------------------------------------------------------------------
# the renderer


def _figure_module():
    try:
        import matplotlib  # noqa: F401
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure
    except ImportError:  # pragma: no cover - depends on the installation
        raise SkewpendError("animations need matplotlib (a dependency of skewpend): pip install matplotlib") from None
    return Figure, FigureCanvasAgg


def _deg_wrapped(angle: float) -> float:
    d = math.degrees(angle) % 360.0
    return d - 360.0 if d > 180.0 else d


def _alpha_is_skew(params) -> bool:
    """Whether ``alpha`` is the angle between the hinge axes (default axes ``k`` and ``e0(alpha)``)."""
    return (getattr(params, "alpha", None) is not None and getattr(params, "axis1", None) is None
            and getattr(params, "axis2", None) is None)


def _skew_angle(params, axes: np.ndarray) -> float:
    """The skew angle [rad]: ``alpha`` for the default axes, else the angle between the axes,
    which every row keeps (``e = P1 . e0`` turns about ``n1``, so ``n1 . e`` is constant)."""
    if _alpha_is_skew(params):
        return float(params.alpha)
    c = float(np.clip(np.dot(axes[0, 0:3], axes[0, 3:6]), -1.0, 1.0))
    return math.acos(c)


def _title(params, skew: float) -> Tuple[str, str]:
    if _alpha_is_skew(params):
        line1 = f"Double pendulum with skewed hinge axes:  α = {math.degrees(skew):.4g}°"
    else:
        line1 = f"Double pendulum with skewed hinge axes:  ∠(n₁, e) = {math.degrees(skew):.4g}°"
    skip = ("alpha",) if _alpha_is_skew(params) else ()  # then alpha is in the first line
    return line1, parameter_text(params, skip=skip, symbols=True, sep=",  ")


class FrameRenderer:
    """Draws the frames of one trajectory on one reused Matplotlib figure (Agg canvas).

    ``draw(k)`` draws frame ``k`` and returns its :class:`FrameScene`; ``rgb()`` gives the pixels
    (h, w, 3) uint8.  ``fig``, ``ax`` (an ``Axes3D``) and ``artists`` are public so the drawing
    can be inspected: ``artists["axis1"]``, ``artists["axis2"]`` are ``Line3D`` (their 3-D data is
    the hinge axis segment in plot coordinates, :func:`world_to_plot`), ``"solids"`` the shaded rods
    and hinge pins (``Poly3DCollection``), ``"heads"`` the arrow heads, ``"trail"``
    (``Line3DCollection``), ``"shadows"``, ``"readout"`` (figure text), ``"axis2_label"``.
    """

    def __init__(self, tr, *, size: Sequence[int] = DEFAULT_SIZE, dpi: float = DEFAULT_DPI,
                 trail: float = DEFAULT_TRAIL, speed: float = 1.0,
                 view: Optional[Tuple[float, float]] = None) -> None:
        Figure, FigureCanvasAgg = _figure_module()
        from matplotlib.lines import Line2D
        from matplotlib.ticker import MaxNLocator
        import mpl_toolkits.mplot3d  # noqa: F401  (registers the 3d projection)
        from mpl_toolkits.mplot3d.art3d import Line3DCollection, Poly3DCollection

        self.size = _frame_size(size)
        self.dpi = checks.positive("dpi", dpi)
        self.geometry = _Geometry(tr, trail)
        self.speed = float(speed)
        g = self.geometry
        # enough decimals that consecutive frames show different times
        step = float(np.min(np.diff(g.t))) if g.t.size > 1 else 1.0
        self.t_decimals = int(min(9, max(3, math.ceil(-math.log10(step)) + 1))) if step > 0 else 3
        R = g.reach
        self.radius = ROD_RADIUS * R
        w, h = self.size
        # a hair over the exact size, so Agg's int() truncation gives exactly w x h
        self.fig = fig = Figure(figsize=((w + 0.01) / self.dpi, (h + 0.01) / self.dpi), dpi=self.dpi, facecolor="white")
        self.canvas = FigureCanvasAgg(fig)
        # text sizes in points (so dpi scales them), by default 9 pt at 640 x 480 and 100 dpi
        small = max(5.0, min(9.0, 9.0 * min(w / 640.0, h / 480.0)))
        self.fontsize = small
        renderer = self.canvas.get_renderer()
        px = lambda artist: artist.get_window_extent(renderer)  # noqa: E731

        def fit_width(text, limit=0.98 * w):
            for _ in range(4):  # shrink a line that is wider than the frame
                width = px(text).width
                if width <= limit:
                    break
                text.set_fontsize(text.get_fontsize() * limit / width * 0.99)

        # title and parameters (static), shrunk to the frame's width
        self.skew = _skew_angle(tr.params, g.axes)
        self.uses_alpha = _alpha_is_skew(tr.params)
        line1, line2 = _title(tr.params, self.skew)
        pad = 3.0 / h
        title = fig.text(0.5, 1.0 - pad, line1, ha="center", va="top", fontsize=small + 2, fontweight="bold")
        fit_width(title)
        y2 = px(title).y0 / h - 0.3 * small / 72 * self.dpi / h
        subtitle = fig.text(0.5, y2, line2, ha="center", va="top", fontsize=small, color="0.25")
        fit_width(subtitle)
        top = px(subtitle).y0 / h - pad

        # legend (static) at the bottom: three columns, or two, or none if it would crowd the frame
        # (frames narrower than 400 px have none)
        ticks = MaxNLocator(8, steps=[1, 2, 2.5, 5, 10]).tick_values(-R, R)
        self.grid_step = float(ticks[1] - ticks[0])
        self._ticks = ticks[np.abs(ticks) <= R + 1e-12]
        handles = [
            Line2D([], [], color=_COLORS["rod1"], lw=5, solid_capstyle="round", label="rod 1 (a)"),
            Line2D([], [], color=_COLORS["rod2"], lw=5, solid_capstyle="round", label="rod 2 (b)"),
            Line2D([], [], color=_COLORS["axis1"], lw=2, marker=">", ms=5, label="hinge 1 axis n₁ (fixed)"),
            Line2D([], [], color=_COLORS["axis2"], lw=2, marker=">", ms=5, label="hinge 2 axis e = P₁·e₀ (turns with rod 1)"),
            Line2D([], [], color=_COLORS["trail"], lw=1.6, label=f"tip trail (last {g.trail:g} s)" if g.trail > 0 else "tip trail (off)"),
            Line2D([], [], color=(0.80, 0.80, 0.83), lw=1, label=f"floor grid {self.grid_step:g} m"),
        ]
        bottom = pad
        self.legend = None
        for ncol in (3, 2) if w >= 400 else ():
            legend = fig.legend(handles=handles, loc="lower center", ncol=ncol, fontsize=small - 0.5, frameon=False,
                                bbox_to_anchor=(0.5, 0.0), handlelength=1.8, columnspacing=1.2, handletextpad=0.5,
                                borderaxespad=0.3)
            box = px(legend)
            if box.width <= w and box.height <= 0.2 * h:
                self.legend = legend
                bottom = box.y1 / h
                break
            legend.remove()

        ax = fig.add_axes((0.0, bottom, 1.0, top - bottom), projection="3d")
        self.ax = ax
        ax.set_proj_type("ortho")
        ax.set_axis_off()
        n1 = g.axes[0, 0:3]
        # the second axis where rod 1 hangs most nearly vertical (phi nearest 0): about e0
        hanging = int(np.argmin(np.abs(np.angle(np.exp(1j * g.y[:, 0])))))
        self.view = _view(view) if view is not None else choose_view(n1, g.axes[hanging, 3:6])
        ax.view_init(elev=self.view[0], azim=self.view[1], roll=0)

        # camera-fixed directions (plot coordinates) and the light
        self.eye = _eye(*self.view)
        up = np.array([0.0, 0.0, 1.0])
        right = _unit(np.cross(up, self.eye)) if abs(self.eye[2]) < 0.999 else _unit(np.cross(self.eye, [1.0, 0.0, 0.0]))
        screen_up = np.cross(self.eye, right)
        self.light = _unit(0.9 * self.eye + 0.7 * screen_up - 0.5 * right)
        self.half_vector = _unit(self.light + self.eye)

        # the floor: a grid with round spacing (the scene's scale), just below the reach
        self.floor = -1.02 * R
        ticks = self._ticks
        lo, hi = float(ticks[0]), float(ticks[-1])
        corners = [np.array([x, y, self.floor]) for x in (lo, hi) for y in (lo, hi)]
        # the world basis i, j, k (j down) at the floor corner on the camera's left
        corner = min(corners, key=lambda c: float(c @ right) - 0.5 * float(c @ self.eye))
        tl = 0.22 * R
        triad_origin = corner + np.array([0.0, 0.0, tl])
        triad = [(world_to_plot(v), name) for v, name in (([1.0, 0.0, 0.0], "i"), ([0.0, 1.0, 0.0], "j"), ([0.0, 0.0, 1.0], "k"))]

        # view limits fixed by the reach R = a + b: everything drawn (the sphere of radius R about
        # the pivot, the floor, the triad) fills the axes; the box centre is put at the centre of
        # that content on screen, the limits form a cube (equal scales), the zoom fits it
        content = [R * right, -R * right, -R * screen_up] + corners
        content += [triad_origin + 1.3 * tl * v for v, _ in triad]
        # upwards only as far as this run's rods and hinge axes (with arrow heads, labels) reach
        reach_axis = g.half + (HEAD_LENGTH + LABEL_GAP) * R
        tips = world_to_plot(g.tips.reshape(-1, 2, 3))
        e = world_to_plot(g.axes[:, 3:6])
        moving = np.concatenate([
            tips.reshape(-1, 3), tips[:, 0] + reach_axis * e, tips[:, 0] - reach_axis * e,
            reach_axis * world_to_plot(g.axes[:, 0:3]), -reach_axis * world_to_plot(g.axes[:, 0:3]),
        ])
        content.append(moving[np.argmax(moving @ screen_up)])
        sr = np.array([c @ right for c in content])
        su = np.array([c @ screen_up for c in content])
        su = np.append(su, su.max() + 0.04 * R)
        mid_r, mid_u = 0.5 * (sr.max() + sr.min()), 0.5 * (su.max() + su.min())
        centre = mid_r * right + (mid_u / screen_up[2]) * up if abs(screen_up[2]) > 1e-6 else mid_r * right + mid_u * screen_up
        lim = 1.08 * R
        ax.set_xlim(centre[0] - lim, centre[0] + lim)
        ax.set_ylim(centre[1] - lim, centre[1] + lim)
        ax.set_zlim(centre[2] - lim, centre[2] + lim)
        ax.set_box_aspect((1.0, 1.0, 1.0), zoom=1.0)
        self.canvas.draw()
        px = self._pixels_per_metre(right, screen_up)
        # Axes3D draws in a square box centred in its rectangle; nothing is clipped to that box
        # (clip_on=False below), so the content may use the whole rectangle
        rect = ax.get_position(original=True)
        zoom = 0.97 * min(rect.width * w / (px[0] * np.ptp(sr)), rect.height * h / (px[1] * np.ptp(su)))
        ax.set_box_aspect((1.0, 1.0, 1.0), zoom=zoom)
        self.canvas.draw()
        self.pixels_per_metre = float(np.mean(self._pixels_per_metre(right, screen_up)))

        grid = [np.array([[v, lo, self.floor], [v, hi, self.floor]]) for v in ticks]
        grid += [np.array([[lo, v, self.floor], [hi, v, self.floor]]) for v in ticks]
        ax.add_collection3d(Line3DCollection(grid, colors=[(0.80, 0.80, 0.83, 1.0)], linewidths=0.6))
        for vec, name in triad:
            end = triad_origin + tl * vec
            ax.plot(*np.stack([triad_origin, end]).T, color="0.45", lw=1.0)
            lab = triad_origin + 1.3 * tl * vec
            ax.text(lab[0], lab[1], lab[2], name, color="0.35", fontsize=small, fontstyle="italic", ha="center", va="center")
        # roof plate at the pivot: a square in the plot's horizontal plane
        s = 0.16 * R
        roof = np.array([[[-s, -s, 0.0], [s, -s, 0.0], [s, s, 0.0], [-s, s, 0.0]]])
        ax.add_collection3d(Poly3DCollection(roof, facecolors=[(*_COLORS["roof"], 0.55)], edgecolors=[(0.3, 0.3, 0.3, 0.8)], linewidths=0.6))

        # moving artists (animated: left out of the cached background)
        lw_rod = 2.0 * self.radius * self.pixels_per_metre * 72.0 / self.dpi
        self.artists: Dict[str, object] = {}
        self.artists["shadows"] = Line3DCollection([np.zeros((2, 3))] * 2, colors=[_COLORS["shadow"]], linewidths=max(1.0, lw_rod), capstyle="round", animated=True)
        self.artists["trail"] = Line3DCollection([np.zeros((2, 3))], linewidths=1.6, animated=True)
        self.artists["solids"] = Poly3DCollection(np.zeros((1, 4, 3)), linewidths=0.6, animated=True)
        for name in ("shadows", "trail", "solids"):
            ax.add_collection3d(self.artists[name])
        (self.artists["axis1"],) = ax.plot([0, 0], [0, 0], [0, 0], color=_COLORS["axis1"], lw=2.0, solid_capstyle="butt", animated=True)
        (self.artists["axis2"],) = ax.plot([0, 0], [0, 0], [0, 0], color=_COLORS["axis2"], lw=2.0, solid_capstyle="butt", animated=True)
        self.artists["heads"] = Poly3DCollection(np.zeros((1, 4, 3)), linewidths=0.4, animated=True)
        ax.add_collection3d(self.artists["heads"])
        label_kw = dict(fontsize=small + 1, fontweight="bold", ha="center", va="center", animated=True)
        self.artists["axis1_label"] = ax.text(0, 0, 0, "n₁", color=_COLORS["axis1"], **label_kw)
        self.artists["axis2_label"] = ax.text(0, 0, 0, "e", color=_COLORS["axis2"], **label_kw)
        (self.artists["axis1_ref"],) = ax.plot([0, 0], [0, 0], [0, 0], color=_COLORS["axis1"], lw=1.2, ls=(0, (2, 2)), alpha=0.9, animated=True)
        (self.artists["skew_arc"],) = ax.plot([0, 0], [0, 0], [0, 0], color="0.15", lw=1.1, animated=True)
        self.artists["skew_label"] = ax.text(0, 0, 0, "α" if self.uses_alpha else "∠", color="0.1", fontsize=small + 1, ha="center", va="center", animated=True)
        self.artists["readout"] = fig.text(
            0.015, top - 0.01, "", ha="left", va="top", family="DejaVu Sans Mono", fontsize=small, animated=True,
            bbox=dict(boxstyle="round,pad=0.35", fc=(1, 1, 1, 0.85), ec="0.75", lw=0.6),
        )

        for artist in ax.get_children():
            artist.set_clip_on(False)

        # draw the static background once and cache it
        self.canvas.draw()
        if self.canvas.get_width_height() != (w, h):  # pragma: no cover - guarded by the +0.01 above
            raise SkewpendError(f"the canvas is {self.canvas.get_width_height()} pixels, expected {w}x{h}")
        self._background = self.canvas.copy_from_bbox(fig.bbox)
        self.scene: Optional[FrameScene] = None

    # -- helpers -------------------------------------------------------------------------------

    def _pixels_per_metre(self, right: np.ndarray, screen_up: np.ndarray) -> np.ndarray:
        """Screen scale of the orthographic plot along the screen's horizontal and vertical [px/m]."""
        from mpl_toolkits.mplot3d import proj3d

        pts = np.array([np.zeros(3), right, screen_up])
        x, y, _ = proj3d.proj_transform(pts[:, 0], pts[:, 1], pts[:, 2], self.ax.get_proj())
        disp = self.ax.transData.transform(np.column_stack([x, y]))
        return np.array([np.linalg.norm(disp[1] - disp[0]), np.linalg.norm(disp[2] - disp[0])])

    def _shade(self, normals: np.ndarray, base: np.ndarray) -> np.ndarray:
        """RGBA per facet: ambient + Lambert + a little specular, fixed light in camera space."""
        lam = np.clip(normals @ self.light, 0.0, None)
        spec = np.clip(normals @ self.half_vector, 0.0, None) ** 24
        rgb = base * (0.38 + 0.62 * lam)[:, None] + 0.35 * spec[:, None]
        rgba = np.empty((normals.shape[0], 4))
        rgba[:, :3] = np.clip(rgb, 0.0, 1.0)
        rgba[:, 3] = 1.0
        return rgba

    def _visible(self, quads: np.ndarray, normals: np.ndarray, base) -> Tuple[np.ndarray, np.ndarray]:
        keep = normals @ self.eye > -0.02  # orthographic camera: back faces point away from eye
        return quads[keep], self._shade(normals[keep], np.asarray(base, dtype=float))

    # -- drawing -------------------------------------------------------------------------------

    def draw(self, k: int) -> FrameScene:
        """Draw frame ``k`` onto the canvas; returns the scene it drew."""
        sc = self.geometry.scene(k)
        self.scene = sc
        g, r, ax = self.geometry, self.radius, self.ax
        P = world_to_plot(sc.rods)
        C = world_to_plot(sc.axis_centers)
        D = world_to_plot(sc.axis_directions)
        h = sc.axis_half_length

        # solids: two rods, two hinge pins along their axes
        parts = []
        parts.append(self._visible(*_cylinder(P[0], P[1], r, D[0]), _COLORS["rod1"]))
        parts.append(self._visible(*_cylinder(P[1], P[2], r, D[1]), _COLORS["rod2"]))
        pin = 2.6 * r
        parts.append(self._visible(*_cylinder(C[0] - pin * D[0], C[0] + pin * D[0], 1.45 * r, P[1] - P[0], 1), _COLORS["pin"]))
        parts.append(self._visible(*_cylinder(C[1] - pin * D[1], C[1] + pin * D[1], 1.45 * r, P[2] - P[1], 1), _COLORS["pin"]))
        quads = np.concatenate([q for q, _ in parts])
        colors = np.concatenate([c for _, c in parts])
        solids = self.artists["solids"]
        solids.set_verts(quads)
        solids.set_facecolor(colors)
        solids.set_edgecolor(colors)

        # hinge axes: lines through the hinges, arrow heads at the + ends, labels beyond
        heads, head_colors = [], []
        head_len, head_r = HEAD_LENGTH * g.reach, HEAD_RADIUS * g.reach
        for i, name in ((0, "axis1"), (1, "axis2")):
            seg = world_to_plot(sc.axis_segment(i))
            line = self.artists[name]
            line.set_data_3d(seg[:, 0], seg[:, 1], seg[:, 2])
            q, n = _cone(seg[1], seg[1] + head_len * D[i], head_r)
            heads.append(q)
            head_colors.append(self._shade(n, np.asarray(_COLORS[name])))
            label = C[i] + (h + head_len + LABEL_GAP * g.reach) * D[i]
            self.artists[f"{name}_label"].set_position_3d(label)
        ref = world_to_plot(np.array([sc.axis_centers[1] - h * sc.axis_directions[0], sc.axis_centers[1] + h * sc.axis_directions[0]]))
        self.artists["axis1_ref"].set_data_3d(ref[:, 0], ref[:, 1], ref[:, 2])
        arc = world_to_plot(sc.skew_arc)
        self.artists["skew_arc"].set_data_3d(arc[:, 0], arc[:, 1], arc[:, 2])
        mid = arc[arc.shape[0] // 2]
        self.artists["skew_label"].set_position_3d(C[1] + 1.35 * (mid - C[1]))
        hq = np.concatenate(heads)
        hc = np.concatenate(head_colors)
        self.artists["heads"].set_verts(hq)
        self.artists["heads"].set_facecolor(hc)
        self.artists["heads"].set_edgecolor(hc)

        # trail of rod 2's tip, fading out, and the shadows of the rods on the floor
        trail = self.artists["trail"]
        tp = world_to_plot(sc.trail)
        if tp.shape[0] > 1:
            trail.set_segments(np.stack([tp[:-1], tp[1:]], axis=1))
            rgba = np.empty((tp.shape[0] - 1, 4))
            rgba[:, :3] = _COLORS["trail"]
            rgba[:, 3] = sc.trail_alpha
            trail.set_color(rgba)
            trail.set_visible(True)
        else:
            trail.set_visible(False)
        fl = P.copy()
        fl[:, 2] = self.floor
        self.artists["shadows"].set_segments([fl[0:2], fl[1:3]])

        # readout
        lines = [
            f"t = {sc.t:{8 + self.t_decimals - 3}.{self.t_decimals}f} s" + (f"   ({self.speed:g}× speed)" if self.speed != 1.0 else ""),
            f"φ = {_deg_wrapped(sc.phi):+7.1f}°",
            f"ψ = {_deg_wrapped(sc.psi):+7.1f}°",
            f"E = {sc.energy:+.5g} J",
        ]
        if np.any(g.work != 0.0):
            lines.append(f"W = {sc.work:+.5g} J  (damping, torques)")
        self.artists["readout"].set_text("\n".join(lines))

        # blit: cached background + moving artists, back to front
        renderer = self.canvas.get_renderer()
        self.canvas.restore_region(self._background)
        ax.M = ax.get_proj()
        ax.invM = np.linalg.inv(ax.M)
        for name in ("shadows", "trail", "solids"):
            art = self.artists[name]
            if art.get_visible():
                art.do_3d_projection()
                art.draw(renderer)
        for name in ("axis1_ref", "skew_arc", "axis1", "axis2"):
            self.artists[name].draw(renderer)
        self.artists["heads"].do_3d_projection()
        self.artists["heads"].draw(renderer)
        for name in ("axis1_label", "axis2_label", "skew_label", "readout"):
            self.artists[name].draw(renderer)
        return sc

    def rgb(self) -> np.ndarray:
        """The canvas as an (h, w, 3) uint8 array (a copy)."""
        buf = np.asarray(self.canvas.buffer_rgba())
        return np.ascontiguousarray(buf[:, :, :3])

    def close(self) -> None:
        self.fig.clear()


# --------------------------------------------------------------------------------------------
# validation


def _view(view) -> Tuple[float, float]:
    try:
        elev, azim = (float(v) for v in view)
        if not (math.isfinite(elev) and math.isfinite(azim)):
            raise ValueError
    except (TypeError, ValueError):
        raise ParameterError(f"view must be two numbers (elevation, azimuth) in degrees, got {view!r}") from None
    return elev, azim


def _frame_size(size) -> Tuple[int, int]:
    try:
        w, h = size
        if any(isinstance(v, bool) or int(v) != v for v in (w, h)):
            raise ValueError
        w, h = int(w), int(h)
    except (TypeError, ValueError):
        raise ParameterError(f"size must be two whole numbers (width, height) in pixels, got {size!r}") from None
    if w < MIN_EDGE or h < MIN_EDGE or w > 7680 or h > 4320:
        raise ParameterError(f"size must be between {MIN_EDGE}x{MIN_EDGE} and 7680x4320 pixels, got {w}x{h}")
    return w, h


def check_frame_times(t, fps: float, speed: float) -> None:
    """Refuse a trajectory whose rows are not exactly the frame times ``k * speed / fps``."""
    t = np.asarray(t, dtype=float)
    step = speed / fps
    grid = np.arange(t.size) * step
    tol = 1e-9 * step + 8.0 * np.finfo(float).eps * np.abs(grid)
    bad = np.nonzero(~(np.abs(t - grid) <= tol))[0]
    if bad.size:
        k = int(bad[0])
        raise ParameterError(
            f"the trajectory's rows are not the frame times k*speed/fps = k*{step:.6g} s (fps={fps:g}, speed={speed:g}): "
            f"t[{k}] = {t[k]:.9g} s, expected {grid[k]:.9g} s; simulate with dt_out=speed/fps"
        )


def check_output(out) -> Path:
    """The output path: a known suffix, not a directory, in an existing writable directory."""
    from ..io import check_output_path

    return check_output_path(out, SUFFIXES, option="animation output")


# --------------------------------------------------------------------------------------------
# writers


def _ffmpeg():
    try:
        import imageio_ffmpeg
    except ImportError:
        raise SkewpendError(
            "MP4 output needs the ffmpeg that the imageio-ffmpeg wheel ships: pip install imageio-ffmpeg "
            "(a dependency of skewpend); or write a .gif"
        ) from None
    return imageio_ffmpeg


def _write_mp4(tmp: Path, frames, size: Tuple[int, int], fps: float) -> None:
    imageio_ffmpeg = _ffmpeg()
    w, h = size
    # libx264 (the wheel's ffmpeg has it); the temporary file's name has no .mp4: say the format
    writer = imageio_ffmpeg.write_frames(
        str(tmp), (w, h), fps=float(fps), codec="libx264", pix_fmt_in="rgb24", pix_fmt_out="yuv420p",
        quality=None, macro_block_size=2, ffmpeg_log_level="error",
        output_params=["-crf", "18", "-preset", "veryfast", "-movflags", "+faststart", "-f", "mp4"],
    )
    writer.send(None)
    ok = False
    try:
        for frame in frames:
            writer.send(frame)
        ok = True
    finally:
        if ok:
            writer.close()  # waits for ffmpeg to finish the file
        else:
            # an error or Ctrl-C: stop ffmpeg at once (the temporary file is removed by the caller)
            try:
                writer.throw(KeyboardInterrupt)
            except BaseException:
                pass
    if not tmp.exists() or tmp.stat().st_size == 0:
        raise SkewpendError("ffmpeg wrote no video (see its messages above)")


def _write_gif(tmp: Path, frames, fps: float, sample: np.ndarray) -> None:
    """GIF through Pillow: one global palette (from ``sample``, a few frames stacked), no
    dithering (flat shaded colours), ``1000 / fps`` ms per frame, looping."""
    from PIL import Image

    palette = Image.fromarray(sample, "RGB").quantize(colors=255, method=Image.Quantize.FASTOCTREE, dither=Image.Dither.NONE)
    # the background stays pure white: the entry white maps to becomes exactly white
    entries = palette.getpalette()
    white = Image.new("RGB", (1, 1), (255, 255, 255)).quantize(palette=palette, dither=Image.Dither.NONE).getpixel((0, 0))
    entries[3 * white : 3 * white + 3] = [255, 255, 255]
    palette.putpalette(entries)

    def images():
        for frame in frames:
            yield Image.fromarray(frame, "RGB").quantize(palette=palette, dither=Image.Dither.NONE)

    it = images()
    first = next(it)
    first.save(tmp, format="GIF", save_all=True, append_images=it, duration=1000.0 / fps, loop=0)


def animate(
    tr,
    out,
    *,
    fps: float = 30.0,
    speed: float = 1.0,
    trail: float = DEFAULT_TRAIL,
    size: Sequence[int] = DEFAULT_SIZE,
    dpi: float = DEFAULT_DPI,
    view: Optional[Tuple[float, float]] = None,
    progress: Optional[Callable[[int, int], None]] = None,
) -> Path:
    """Render every row of ``tr`` as one frame and write ``out`` (``.mp4`` or ``.gif``).

    ``tr`` must be sampled exactly at the frame times ``k * speed / fps`` (make it with
    ``skewpend.simulate(params, y0, duration * speed, dt_out=speed / fps)``), else
    :class:`~skewpend.ParameterError`.  ``fps``: frames per second of the video; ``speed``:
    seconds of motion per second of video (0.5 = slow motion); ``trail``: seconds of motion the
    fading trail of rod 2's tip covers (0: none); ``size``: (width, height) in pixels (even for
    MP4); ``dpi``: scales text and lines; ``view``: camera (elev, azim) in degrees, plot
    coordinates (default: :func:`choose_view`); ``progress(done, total)`` is called after each
    frame.

    MP4 is H.264 (yuv420p) through the ffmpeg of the ``imageio-ffmpeg`` wheel; GIF goes through
    Pillow (``1000 / fps`` ms per frame -- GIF stores hundredths of a second --, looping).  The
    file is written to a temporary file beside ``out`` and renamed at the end; on any error or
    Ctrl-C the temporary file is removed and ``out`` is untouched.  Returns ``Path(out)``.
    """
    path = check_output(out)
    fps = checks.positive("fps", fps)
    speed = checks.positive("speed", speed)
    w, h = _frame_size(size)
    fmt = path.suffix.lower()
    if fmt == ".mp4" and (w % 2 or h % 2):
        raise ParameterError(f"MP4 (H.264, yuv420p) needs an even width and height, got {w}x{h}")
    checks.progress_callable(progress)
    if view is not None:
        view = _view(view)
    checks.positive("dpi", dpi)
    checks.finite_seconds("trail", trail)
    if fmt == ".mp4":
        _ffmpeg()
    if not getattr(tr, "kept", True):
        raise ParameterError("the trajectory kept only its first and last rows (keep=False); animate needs every row")
    check_frame_times(tr.t, fps, speed)

    renderer = FrameRenderer(tr, size=(w, h), dpi=dpi, trail=trail, speed=speed, view=view)
    total = renderer.geometry.t.size

    def frames():
        for k in range(total):
            renderer.draw(k)
            yield renderer.rgb()
            if progress is not None:
                progress(k + 1, total)

    try:
        with atomic_path(path) as tmp:
            if fmt == ".mp4":
                _write_mp4(tmp, frames(), (w, h), fps)
            else:
                sample = []
                for k in sorted({0, total // 3, (2 * total) // 3, total - 1}):  # for the palette
                    renderer.draw(k)
                    sample.append(renderer.rgb())
                _write_gif(tmp, frames(), fps, np.concatenate(sample, axis=0))
    finally:
        renderer.close()
    return path
