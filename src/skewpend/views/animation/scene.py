"""The scene of a frame, in world and plot coordinates, as pure NumPy: the sizes and colours of the
drawing, the coordinate map, the camera's choice, the geometry of every frame (:class:`FrameScene`,
:func:`frame_scene`), the meshes of rods and arrow heads, and the checks of a view and a frame size."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Tuple

import numpy as np

from ... import checks
from ...errors import ParameterError, SkewpendError
from ..drawing import drawn_depth, drawn_frame, drawn_reach, link_points

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

SCENE_COLORS = {"pin": (0.35, 0.35, 0.38), "trail": (0.42, 0.24, 0.60), "shadow": (0.0, 0.0, 0.0, 0.22),
                "roof": (0.55, 0.55, 0.58)}
#: The rods' and hinge axes' colours in turn (rod k, hinge k; the double pendulum's two first).
CHAIN_ROD_COLORS = ((0.23, 0.43, 0.68), (0.90, 0.50, 0.13), (0.17, 0.60, 0.33), (0.58, 0.40, 0.74),
                    (0.55, 0.34, 0.29), (0.84, 0.38, 0.61), (0.50, 0.50, 0.50), (0.74, 0.74, 0.13))
CHAIN_HINGE_COLORS = ((0.05, 0.55, 0.40), (0.80, 0.08, 0.40), (0.12, 0.35, 0.75), (0.85, 0.45, 0.0),
                      (0.45, 0.20, 0.60), (0.10, 0.55, 0.65), (0.60, 0.45, 0.10), (0.35, 0.35, 0.35))


def rod_color(i: int):
    """Rod ``i``'s colour (0-based)."""
    return CHAIN_ROD_COLORS[i % len(CHAIN_ROD_COLORS)]


def hinge_color(i: int):
    """Hinge axis ``i``'s colour (0-based)."""
    return CHAIN_HINGE_COLORS[i % len(CHAIN_HINGE_COLORS)]


_SIDES = 12  # facets around a rod
_SEGMENTS = 4  # pieces along a rod (keeps the painter's sort right where rods meet)


def world_to_plot(points) -> np.ndarray:
    """World ``(x, y, z)`` (``y`` down) -> plot ``(X, Y, Z) = (x, z, -y)``; shape (..., 3)."""
    p = np.asarray(points, dtype=float)
    return np.stack([p[..., 0], p[..., 2], -p[..., 1]], axis=-1)


def plot_to_world(points) -> np.ndarray:
    """Inverse of :func:`world_to_plot`."""
    p = np.asarray(points, dtype=float)
    return np.stack([p[..., 0], -p[..., 2], p[..., 1]], axis=-1)


def unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def eye(elev: float, azim: float) -> np.ndarray:
    """Unit vector from the scene towards the camera, plot coordinates (Matplotlib's convention)."""
    el, az = math.radians(elev), math.radians(azim)
    return np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])


def _angle_to_line(v: np.ndarray, d: np.ndarray) -> float:
    """Angle [deg] between the direction ``v`` and the line along ``d`` (0..90)."""
    c = abs(float(np.dot(unit(v), unit(d))))
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
        seen_from = eye(elev, azim)
        return min(_angle_to_line(seen_from, n1), _angle_to_line(seen_from, e))

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


@dataclass(frozen=True)
class FrameScene:
    """The 3-D geometry of frame ``k`` in WORLD coordinates (``y`` down), as it is drawn.

    * ``rods`` -- (n + 1, 3): the hinges and the last rod's end (``n = 2`` rods for the double pendulum, a
      chain's links; :func:`skewpend.views.drawing.link_points`); rod ``i`` is drawn from ``rods[i]`` (its
      hinge) to ``rods[i + 1]`` (the next hinge: the rod's end where the hinge sits there);
    * ``axis_centers`` -- (n, 3): where the hinge axes are drawn: the hinges;
    * ``axis_directions`` -- (n, 3): unit vectors ``n1`` and ``e = P1 . e0`` (``tr.axes()[k]``; a
      chain's every hinge axis);
    * ``axis_half_length`` -- each axis is drawn from ``centre - h d`` to ``centre + h d``
      (:meth:`axis_segment`), the arrow head at the ``+`` end;
    * ``trail`` -- (m, 3): rod 2's tip over the last ``trail`` seconds, oldest first, ending at
      ``rods[2]``; ``trail_alpha`` -- (m - 1,): opacity of each trail segment (fading out);
    * ``skew_arc`` -- (m, 3): the arc at ``tip1`` from the direction ``n1`` (drawn there as a dotted
      reference line, ``centre = tip1``, ``direction = n1``) to ``e``: the skew angle;
    * ``skew_arcs`` -- one such arc at every hinge after the first (from the parent's axis to the
      hinge's: a chain's skew angles), ``skew_arc`` the first;
    * ``t``, ``phi``, ``psi``, ``energy``, ``work`` -- the readout's values (``q`` every angle).
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
    skew_arcs: Tuple[np.ndarray, ...] = ()
    q: Tuple[float, ...] = ()

    def axis_segment(self, i: int) -> np.ndarray:
        """End points (2, 3) of hinge axis ``i`` (0: the roof hinge, 1: the second hinge), world."""
        c, d, h = self.axis_centers[i], self.axis_directions[i], self.axis_half_length
        return np.array([c - h * d, c + h * d])


class Geometry:
    """Per-row data of a trajectory, computed once: rod ends, hinge axes, reach, trail rows."""

    def __init__(self, tr, trail: float = DEFAULT_TRAIL) -> None:
        if not getattr(tr, "kept", True):
            raise ParameterError("the trajectory kept only its first and last rows (keep=False); animate needs every row")
        t = np.asarray(tr.t, dtype=float)
        if t.ndim != 1 or t.size < 1:
            raise ParameterError("the trajectory has no rows to animate")
        trail = checks.finite_seconds("trail", trail)
        self.t = t
        self.y = np.asarray(tr.y, dtype=float)
        self.energy = np.asarray(tr.energy, dtype=float)
        self.work = np.asarray(tr.work, dtype=float)
        self.n = n = self.y.shape[1] // 2  # rods: 2, or a chain's links
        #: the drawn chain a row (rows, n + 1, 3): the hinges and the last rod's end (link i from point i to i + 1)
        self.points = link_points(tr.params, self.y, tr.tips())
        #: the drawn links' ends a row (rows, 3 n): the next hinges and the last rod's end
        self.tips = self.points[:, 1:].reshape(-1, 3 * n)
        self.axes = np.asarray(tr.axes(), dtype=float).reshape(-1, 3 * n)
        if self.tips.shape[0] != t.size or self.axes.shape[0] != t.size:
            raise SkewpendError("the trajectory's rod ends or axes do not match its rows")
        #: where the view looks when hinge 1 is not at the roof: (centre, radius) [m] (drawing.drawn_frame), else None
        self.frame = drawn_frame(tr.params)
        #: the picture's length scale [m]: the drawn reach from the roof, or the radius of the ball about hinge 1
        self.reach = drawn_reach(tr.params) if self.frame is None else self.frame[1]
        #: the deepest the drawn chain reaches below the roof (the reach, but for an arm turning horizontally)
        self.depth = drawn_depth(tr.params)
        self.half = AXIS_HALF_LENGTH * self.reach
        self.trail = trail
        # first row of each frame's trail: the earliest row with t >= t_k - trail
        self.trail_start = np.searchsorted(t, t - trail - 1e-9 * max(trail, 1.0), side="left")

    def scene(self, k: int) -> FrameScene:
        n = self.t.size
        if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or not -n <= k < n:
            raise ParameterError(f"frame index must be a whole number in 0..{n - 1}, got {k!r}")
        k = int(k) % n
        tips, m = self.tips, self.n
        rods = self.points[k].copy()
        centers = rods[:m].copy()
        dirs = self.axes[k].reshape(m, 3).copy()
        j0 = int(self.trail_start[k])
        trail = tips[j0 : k + 1, 3 * (m - 1):3 * m].copy()
        count = trail.shape[0]
        alpha = np.linspace(0.0, 0.9, count)[1:] if count > 1 else np.zeros(0)
        arcs = tuple(_arc_points(centers[i], dirs[i - 1], dirs[i], ARC_RADIUS * self.half) for i in range(1, m))
        return FrameScene(k=k, t=float(self.t[k]), phi=float(self.y[k, 0]),
                          psi=float(self.y[k, 1]) if m >= 2 else math.nan, energy=float(self.energy[k]),
                          work=float(self.work[k]), rods=rods, axis_centers=centers, axis_directions=dirs,
                          axis_half_length=self.half, trail=trail, trail_alpha=alpha,
                          skew_arc=arcs[0] if arcs else np.zeros((0, 3)), skew_arcs=arcs,
                          q=tuple(float(x) for x in self.y[k, :m]))


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
    """The :class:`FrameScene` of frame ``k`` (row ``k`` of ``tr``); ``trail``: seconds of motion the tip's
    trail covers."""
    return Geometry(tr, trail).scene(k)


# -- solids: shaded cylinders and cones as quadrilaterals (plot coordinates) --------------------
def _frame_about(d: np.ndarray, ref: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    u = np.cross(ref, d)
    if np.linalg.norm(u) < 1e-6:
        u = np.cross(np.array([1.0, 0.0, 0.0]) if abs(d[0]) < 0.9 else np.array([0.0, 1.0, 0.0]), d)
    u = unit(u)
    return u, np.cross(d, u)


def _fan(centre: np.ndarray, ring: np.ndarray) -> np.ndarray:
    """A disc about ``centre`` as a fan of quads (centre, v_i, v_i+1, v_i+2) over the points ``ring`` (S + 1, 3)."""
    idx = np.arange(0, _SIDES, 2)
    return np.stack([np.broadcast_to(centre, (idx.size, 3)), ring[idx], ring[idx + 1], ring[(idx + 2) % (_SIDES + 1)]],
                    axis=1)


_THETA = np.linspace(0.0, 2.0 * np.pi, _SIDES + 1)
_COS, _SIN = np.cos(_THETA), np.sin(_THETA)
_CMID, _SMID = np.cos(_THETA[:-1] + np.pi / _SIDES), np.sin(_THETA[:-1] + np.pi / _SIDES)


def cylinder(p: np.ndarray, q: np.ndarray, r: float, ref: np.ndarray, segments: int = _SEGMENTS):
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
    caps = [_fan(p, p + ring), _fan(q, q + ring)]  # the end caps
    cap_normals = [np.broadcast_to(nrm, (caps[0].shape[0], 3)) for nrm in (-d, d)]
    return (np.concatenate([side] + caps), np.concatenate([normals] + cap_normals))


def cone(base: np.ndarray, tip: np.ndarray, r: float):
    """Quads (degenerate: triangles) and normals of a cone (arrow head) plus its base disc."""
    axis = tip - base
    length = float(np.linalg.norm(axis))
    d = axis / length
    u, w = _frame_about(d, np.array([0.0, 0.0, 1.0]))
    ring = base + r * (_COS[:, None] * u + _SIN[:, None] * w)
    tips = np.broadcast_to(tip, (_SIDES, 3))
    quads = np.stack([tips, ring[:-1], ring[1:], tips], axis=1)
    radial = _CMID[:, None] * u + _SMID[:, None] * w
    normals = unit(radial * length + d * r)
    disc = _fan(base, ring)
    return np.concatenate([quads, disc]), np.concatenate([normals, np.broadcast_to(-d, (disc.shape[0], 3))])


def check_view(view) -> Tuple[float, float]:
    try:
        elev, azim = (float(v) for v in view)
        if not (math.isfinite(elev) and math.isfinite(azim)):
            raise ValueError
    except (TypeError, ValueError):
        raise ParameterError(f"view must be two numbers (elevation, azimuth) in degrees, got {view!r}") from None
    return elev, azim


def check_frame_size(size) -> Tuple[int, int]:
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
