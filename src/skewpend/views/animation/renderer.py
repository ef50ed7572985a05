"""The renderer: every frame of one trajectory drawn on one reused Matplotlib 3-D figure."""

from __future__ import annotations

import math
from typing import Dict, Optional, Sequence, Tuple

import numpy as np

from ... import checks
from ...errors import SkewpendError
from ...schema import AXIS_NAMES
from ..style import answers_names, parameter_text
from .scene import (DEFAULT_DPI, DEFAULT_SIZE, DEFAULT_TRAIL, HEAD_LENGTH, HEAD_RADIUS, LABEL_GAP, ROD_RADIUS,
                    SCENE_COLORS, FrameScene, Geometry, check_frame_size, check_view, choose_view, cone, cylinder, eye,
                    hinge_color, rod_color, unit, world_to_plot)

_SUB = str.maketrans("0123456789", "₀₁₂₃₄₅₆₇₈₉")
#: The readout's names of the coordinates the specification names (else the coordinate's own, q₁ …).
READOUT_NAMES = {"phi": "φ", "psi": "ψ"}


def _deg_wrapped(angle: float) -> float:
    d = math.degrees(angle) % 360.0
    return d - 360.0 if d > 180.0 else d


def _named_skew(params) -> Optional[float]:
    """The model's own skew-angle parameter where it sets the hinge axes (``alpha``: the default axes ``k`` and
    ``e0(alpha)``), asked of its parameters; None where the axes are given as vectors."""
    values = params.to_dict()
    if values.get("alpha") is None or values.get("axis1") is not None or values.get("axis2") is not None:
        return None
    return float(values["alpha"])


def _skews(axes: np.ndarray) -> list:
    """The angles [rad] between consecutive hinge axes, which every row keeps (hinge ``i + 1``'s axis turns
    about hinge ``i``'s): from the first row's axes ``(n, 3 n)``."""
    e = axes[0].reshape(-1, 3)
    return [math.acos(float(np.clip(np.dot(a, b), -1.0, 1.0))) for a, b in zip(e, e[1:])]


#: The specification's names of the double pendulum's rods and hinge axes, by its coordinates: (rod, axis,
#: the axis in the legend) -- where the model IS the specification's double pendulum (:func:`is_double_pendulum`).
JOINT_LABELS = {"phi": ("rod 1 (a)", "n₁", "hinge 1 axis n₁ (fixed)"),
                "psi": ("rod 2 (b)", "e", "hinge 2 axis e = P₁·e₀ (turns with rod 1)")}
#: The title's name of the specification's double pendulum (any other model: a chain of n links).
DOUBLE_PENDULUM_TITLE = "Double pendulum with skewed hinge axes"


def is_double_pendulum(model) -> bool:
    """Whether ``model`` is the specification's double pendulum -- its rods ``a``, ``b``, hinge 1's axis ``n1``,
    hinge 2's ``e = P1 e0`` -- asked of the model, never its type: it answers the specification's names
    (:func:`~skewpend.views.style.answers_names`) or its exact model is the double pendulum's parameters
    (``model.exact_model()``: a chain of two with the specification's geometry).  A chain of two links of any
    other geometry (the rotary pendulum's vertical first hinge) is a chain, told by its links."""
    exact = getattr(model, "exact_model", None)
    return answers_names(model) or (callable(exact) and exact() is not None)


def joint_labels(model) -> list:
    """Per joint of ``model``: its link's label, its hinge axis's name and the axis's legend entry -- the
    specification's (``rod 1 (a)``, ``n₁``; ``rod 2 (b)``, ``e = P₁·e₀``) where the model is its double
    pendulum (:func:`is_double_pendulum`), else a chain's: ``link i``, the axis ``eᵢ`` of hinge ``i``
    (fixed for hinge 1, turning with link ``i - 1`` after it)."""
    if is_double_pendulum(model):
        return [JOINT_LABELS[c] for c in model.coordinates]
    out = []
    for i in range(model.n):
        e = f"e{str(i + 1).translate(_SUB)}"
        out.append((f"link {i + 1}", e, f"hinge {i + 1}'s axis {e} " + ("(fixed)" if i == 0 else f"(turns with link {i})")))
    return out


def _title(params, axes: np.ndarray) -> Tuple[str, str]:
    """The title's two lines: the model and its hinge axes' angles (its ``alpha`` where that sets them), and its
    parameters."""
    n, alpha = params.n, _named_skew(params)
    names = [axis for _, axis, _ in joint_labels(params)]
    if alpha is not None:
        skews = f"α = {math.degrees(alpha):.4g}°"
    else:
        skews = ", ".join(f"∠({a}, {b}) = {math.degrees(x):.4g}°" for a, b, x in zip(names, names[1:], _skews(axes)))
    line1 = (DOUBLE_PENDULUM_TITLE if is_double_pendulum(params) else f"Chain of {n} links") + (f":  {skews}" if skews else "")
    skip = ("alpha",) if alpha is not None else ()  # then alpha is in the first line
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
        try:
            from matplotlib.backends.backend_agg import FigureCanvasAgg
            from matplotlib.figure import Figure
        except ImportError:  # pragma: no cover - depends on the installation
            raise SkewpendError("animations need matplotlib (a dependency of skewpend): "
                                "pip install matplotlib") from None
        from matplotlib.lines import Line2D
        from matplotlib.ticker import MaxNLocator
        import mpl_toolkits.mplot3d  # noqa: F401  (registers the 3d projection)
        from mpl_toolkits.mplot3d.art3d import Line3DCollection, Poly3DCollection

        self.size = check_frame_size(size)
        self.dpi = checks.positive("dpi", dpi)
        self.geometry = Geometry(tr, trail)
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
        renderer = self.canvas.get_renderer()
        px = lambda artist: artist.get_window_extent(renderer)  # noqa: E731

        def fit_width(text, limit=0.98 * w):
            for _ in range(4):  # shrink a line that is wider than the frame
                width = px(text).width
                if width <= limit:
                    break
                text.set_fontsize(text.get_fontsize() * limit / width * 0.99)

        # title and parameters (static), shrunk to the frame's width
        alpha = _named_skew(tr.params)
        #: the angle between the first two hinge axes [rad] (the model's alpha where that sets them; 0 for one link)
        self.skew = alpha if alpha is not None else (_skews(g.axes) or [0.0])[0]
        self.uses_alpha = alpha is not None
        line1, line2 = _title(tr.params, g.axes)
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
        self.n = n = g.n
        joints = joint_labels(tr.params)
        handles = [Line2D([], [], color=rod_color(i), lw=5, solid_capstyle="round", label=rod)
                   for i, (rod, _, _) in enumerate(joints)]
        handles += [Line2D([], [], color=hinge_color(i), lw=2, marker=">", ms=5, label=legend)
                    for i, (_, _, legend) in enumerate(joints)]
        self.axis_labels = [axis for _, axis, _ in joints]
        handles += [
            Line2D([], [], color=SCENE_COLORS["trail"], lw=1.6, label=f"tip trail (last {g.trail:g} s)" if g.trail > 0 else "tip trail (off)"),
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
        second = g.axes[hanging, 3:6] if n >= 2 else np.array([1.0, 0.0, 0.0])
        self.view = check_view(view) if view is not None else choose_view(n1, second)
        ax.view_init(elev=self.view[0], azim=self.view[1], roll=0)

        # camera-fixed directions (plot coordinates) and the light
        self.eye = eye(*self.view)
        up = np.array([0.0, 0.0, 1.0])
        right = unit(np.cross(up, self.eye)) if abs(self.eye[2]) < 0.999 else unit(np.cross(self.eye, [1.0, 0.0, 0.0]))
        screen_up = np.cross(self.eye, right)
        self.light = unit(0.9 * self.eye + 0.7 * screen_up - 0.5 * right)
        self.half_vector = unit(self.light + self.eye)

        # the floor: a grid with round spacing (the scene's scale), just below the deepest the chain reaches
        self.floor = -1.02 * max(g.depth, 0.1 * R)  # a chain above its roof: the floor a tenth of the reach below it
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
        if g.frame is None:
            content = [R * right, -R * right, -g.depth * screen_up] + corners
        else:  # hinge 1 away from the roof: the sphere about it that the drawn chain stays in, the roof, the floor
            c, r = world_to_plot(np.asarray(g.frame[0], dtype=float)), g.frame[1]
            content = [c + r * right, c - r * right, c - r * screen_up, np.zeros(3)] + corners
        content += [triad_origin + 1.3 * tl * v for v, _ in triad]
        # upwards only as far as this run's rods and hinge axes (with arrow heads, labels) reach
        reach_axis = g.half + (HEAD_LENGTH + LABEL_GAP) * R
        tips = world_to_plot(g.tips.reshape(-1, n, 3))  # the drawn links' ends: the next hinges, the last rod's end
        first = world_to_plot(g.points[:, 0])  # hinge 1
        moving = [tips.reshape(-1, 3), first + reach_axis * world_to_plot(g.axes[:, 0:3]),
                  first - reach_axis * world_to_plot(g.axes[:, 0:3])]
        for i in range(1, n):  # hinge i + 1's axis at rod i's drawn end
            e = world_to_plot(g.axes[:, 3 * i:3 * i + 3])
            moving += [tips[:, i - 1] + reach_axis * e, tips[:, i - 1] - reach_axis * e]
        moving = np.concatenate(moving)
        content.append(moving[np.argmax(moving @ screen_up)])
        sr = np.array([c @ right for c in content])
        su = np.array([c @ screen_up for c in content])
        su = np.append(su, su.max() + 0.04 * R)
        mid_r, mid_u = 0.5 * (sr.max() + sr.min()), 0.5 * (su.max() + su.min())
        centre = mid_r * right + (mid_u / screen_up[2]) * up if abs(screen_up[2]) > 1e-6 else mid_r * right + mid_u * screen_up
        lim = 1.08 * R
        for set_lim, c in zip((ax.set_xlim, ax.set_ylim, ax.set_zlim), centre):
            set_lim(c - lim, c + lim)
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
        ax.add_collection3d(Poly3DCollection(roof, facecolors=[(*SCENE_COLORS["roof"], 0.55)], edgecolors=[(0.3, 0.3, 0.3, 0.8)], linewidths=0.6))

        # moving artists (animated: left out of the cached background)
        lw_rod = 2.0 * self.radius * self.pixels_per_metre * 72.0 / self.dpi
        self.artists: Dict[str, object] = {}
        self.artists["shadows"] = Line3DCollection([np.zeros((2, 3))] * n, colors=[SCENE_COLORS["shadow"]], linewidths=max(1.0, lw_rod), capstyle="round", animated=True)
        self.artists["trail"] = Line3DCollection([np.zeros((2, 3))], linewidths=1.6, animated=True)
        self.artists["solids"] = Poly3DCollection(np.zeros((1, 4, 3)), linewidths=0.6, animated=True)
        for name in ("shadows", "trail", "solids"):
            ax.add_collection3d(self.artists[name])
        #: the hinge axes' line artists ("axis1", "axis2": named as the double pendulum's parameters; a chain's
        #: "axis1" ... "axisN"), their labels, and at every hinge after the first the parent's axis (dotted,
        #: "axis1_ref" at hinge 2) and the arc of the skew angle ("skew_arc" at hinge 2)
        self.axis_names = [AXIS_NAMES[i] if i < len(AXIS_NAMES) else f"axis{i + 1}" for i in range(n)]
        self.ref_names = ["axis1_ref"] + [f"axis{i}_ref" for i in range(2, n)]
        self.arc_names = ["skew_arc"] + [f"skew_arc{i + 1}" for i in range(2, n)]
        self.arc_label_names = ["skew_label"] + [f"skew_label{i + 1}" for i in range(2, n)]
        label_kw = dict(fontsize=small + 1, fontweight="bold", ha="center", va="center", animated=True)
        for i, name in enumerate(self.axis_names):
            (self.artists[name],) = ax.plot([0, 0], [0, 0], [0, 0], color=hinge_color(i), lw=2.0, solid_capstyle="butt", animated=True)
            self.artists[f"{name}_label"] = ax.text(0, 0, 0, self.axis_labels[i], color=hinge_color(i), **label_kw)
        self.artists["heads"] = Poly3DCollection(np.zeros((1, 4, 3)), linewidths=0.4, animated=True)
        ax.add_collection3d(self.artists["heads"])
        for i in range(1, n):
            (self.artists[self.ref_names[i - 1]],) = ax.plot([0, 0], [0, 0], [0, 0], color=hinge_color(i - 1), lw=1.2, ls=(0, (2, 2)), alpha=0.9, animated=True)
            (self.artists[self.arc_names[i - 1]],) = ax.plot([0, 0], [0, 0], [0, 0], color="0.15", lw=1.1, animated=True)
            self.artists[self.arc_label_names[i - 1]] = ax.text(0, 0, 0, "α" if self.uses_alpha else "∠", color="0.1", fontsize=small + 1, ha="center", va="center", animated=True)
        #: the readout's names of the angles, one line each for up to three joints (the double pendulum's φ, ψ)
        self.readout_names = ([READOUT_NAMES.get(c, c.translate(_SUB)) for c in tr.params.coordinates]
                               if n <= 3 else [])
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
        return np.column_stack([np.clip(rgb, 0.0, 1.0), np.ones(normals.shape[0])])

    def _visible(self, quads: np.ndarray, normals: np.ndarray, base) -> Tuple[np.ndarray, np.ndarray]:
        keep = normals @ self.eye > -0.02  # orthographic camera: back faces point away from eye
        return quads[keep], self._shade(normals[keep], np.asarray(base, dtype=float))

    def draw(self, k: int) -> FrameScene:
        """Draw frame ``k`` onto the canvas; returns the scene it drew."""
        sc = self.geometry.scene(k)
        self.scene = sc
        g, r, ax = self.geometry, self.radius, self.ax
        P = world_to_plot(sc.rods)
        C = world_to_plot(sc.axis_centers)
        D = world_to_plot(sc.axis_directions)
        h = sc.axis_half_length

        # solids: the rods, a hinge pin along each axis
        n = self.n
        parts = [self._visible(*cylinder(P[i], P[i + 1], r, D[i]), rod_color(i)) for i in range(n)]
        pin = 2.6 * r
        parts += [self._visible(*cylinder(C[i] - pin * D[i], C[i] + pin * D[i], 1.45 * r, P[i + 1] - P[i], 1), SCENE_COLORS["pin"])
                  for i in range(n)]
        _set_facets(self.artists["solids"], np.concatenate([q for q, _ in parts]),
                    np.concatenate([c for _, c in parts]))

        # hinge axes: lines through the hinges, arrow heads at the + ends, labels beyond
        heads, head_colors = [], []
        head_len, head_r = HEAD_LENGTH * g.reach, HEAD_RADIUS * g.reach
        for i, name in enumerate(self.axis_names):
            seg = world_to_plot(sc.axis_segment(i))
            line = self.artists[name]
            line.set_data_3d(seg[:, 0], seg[:, 1], seg[:, 2])
            q, normals = cone(seg[1], seg[1] + head_len * D[i], head_r)
            heads.append(q)
            head_colors.append(self._shade(normals, np.asarray(hinge_color(i))))
            label = C[i] + (h + head_len + LABEL_GAP * g.reach) * D[i]
            self.artists[f"{name}_label"].set_position_3d(label)
        for i in range(1, n):  # at hinge i + 1: the parent's axis (dotted) and the arc of the angle between them
            ref = world_to_plot(np.array([sc.axis_centers[i] - h * sc.axis_directions[i - 1],
                                          sc.axis_centers[i] + h * sc.axis_directions[i - 1]]))
            self.artists[self.ref_names[i - 1]].set_data_3d(ref[:, 0], ref[:, 1], ref[:, 2])
            arc = world_to_plot(sc.skew_arcs[i - 1])
            self.artists[self.arc_names[i - 1]].set_data_3d(arc[:, 0], arc[:, 1], arc[:, 2])
            mid = arc[arc.shape[0] // 2]
            self.artists[self.arc_label_names[i - 1]].set_position_3d(C[i] + 1.35 * (mid - C[i]))
        _set_facets(self.artists["heads"], np.concatenate(heads), np.concatenate(head_colors))

        # trail of rod 2's tip, fading out, and the shadows of the rods on the floor
        trail = self.artists["trail"]
        tp = world_to_plot(sc.trail)
        if tp.shape[0] > 1:
            trail.set_segments(np.stack([tp[:-1], tp[1:]], axis=1))
            trail.set_color(np.column_stack([np.tile(SCENE_COLORS["trail"], (tp.shape[0] - 1, 1)), sc.trail_alpha]))
            trail.set_visible(True)
        else:
            trail.set_visible(False)
        fl = P.copy()
        fl[:, 2] = self.floor
        self.artists["shadows"].set_segments([fl[i:i + 2] for i in range(n)])

        # readout
        lines = [f"t = {sc.t:{8 + self.t_decimals - 3}.{self.t_decimals}f} s" + (f"   ({self.speed:g}× speed)" if self.speed != 1.0 else "")]
        if self.readout_names:  # up to three joints: a line each
            lines += [f"{name} = {_deg_wrapped(x):+7.1f}°" for name, x in zip(self.readout_names, sc.q)]
        else:
            lines.append("q = " + ", ".join(f"{_deg_wrapped(x):+.1f}°" for x in sc.q))
        lines.append(f"E = {sc.energy:+.5g} J")
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
        for name in self.ref_names[:n - 1] + self.arc_names[:n - 1] + self.axis_names:  # the double's axes: named as their parameters
            self.artists[name].draw(renderer)
        self.artists["heads"].do_3d_projection()
        self.artists["heads"].draw(renderer)
        for name in [f"{a}_label" for a in self.axis_names] + self.arc_label_names[:n - 1] + ["readout"]:
            self.artists[name].draw(renderer)
        return sc

    def rgb(self) -> np.ndarray:
        """The canvas as an (h, w, 3) uint8 array (a copy)."""
        buf = np.asarray(self.canvas.buffer_rgba())
        return np.ascontiguousarray(buf[:, :, :3])

    def close(self) -> None:
        self.fig.clear()


def _set_facets(collection, quads: np.ndarray, colors: np.ndarray) -> None:
    """A Poly3DCollection's facets, filled and edged in their colours."""
    collection.set_verts(quads)
    collection.set_facecolor(colors)
    collection.set_edgecolor(colors)
