"""Measured motion of a real double pendulum, in skewpend's coordinates: :class:`Measurements`.

Identification (issue 27) starts from data: times, the two hinge angles, their speeds where they
were measured and the joint torques where they were measured, in one or more *pieces* (each a
stretch of contiguous samples with its own start).  Every reader converts the file's angles to
skewpend's convention once, here, and checks that the result is plausible:

* skewpend's coordinates: ``phi`` the angle of hinge 1, ``psi`` the angle of hinge 2 *relative to
  rod 1*, both zero with the rods hanging, in radians, positive about the hinge axes (``k`` and
  ``e``; with ``j`` pointing down); joint torques ``u = (tau1, tau2)`` [N m] act in the sense of
  their angle (they enter Lagrange's equations as ``Q = u - c q'``).
* a file states its own :class:`Convention` (second angle absolute or relative, zero hanging or
  upright, a sign per angle, degrees or radians); :func:`convert` and :func:`convert_back` are
  the one conversion and its inverse.
* checks, each one :class:`~skewpend.errors.ParameterError` naming the file and piece and what to
  do: wrapped angles (jumps of about 2 pi between samples: unwrapped only when the convention
  says ``wrapped=True``), a free swing whose mean sits near the upright (the other zero), a second
  angle that follows the first as an absolute one would, velocities that run against their
  angles' rate of change, time that does not increase, NaN/inf rows (dropped and counted up to
  ``nonfinite``, a fraction; refused above it), fewer than :data:`MIN_SAMPLES` samples, constant
  angles, pieces shorter than ``min_duration``.  A time step longer than ``gap_factor`` times
  the median step cuts the piece in two.  Nothing is fixed silently: every action is a line in
  ``metadata["actions"]`` and in :meth:`Measurements.summary`.

Readers: :meth:`Measurements.from_arrays` (the one constructor every reader goes through),
:meth:`~Measurements.from_csv` (a column mapping), :meth:`~Measurements.from_mat` (MATLAB cell
arrays of pieces), :meth:`~Measurements.from_kaheman` and :meth:`~Measurements.from_dfki` (the two
measured rigs of ``data/``), :meth:`~Measurements.from_trajectory` (skewpend's own trajectories).
"""

from __future__ import annotations

import csv
import math
from collections import Counter
from dataclasses import dataclass, field, replace
from pathlib import Path
from types import MappingProxyType
from typing import Any, Dict, Iterator, List, Mapping, Optional, Sequence, Tuple, Union

import numpy as np

from ..errors import ParameterError
from ..schema import AXIS_NAMES, TORQUE_NAMES, coordinate_names

__all__ = ["Measurements", "Piece", "Convention", "SKEWPEND", "convert", "convert_back",
           "MIN_SAMPLES", "GAP_FACTOR", "NONFINITE", "KAHEMAN_FILE", "KAHEMAN_PARAMETERS_FILE", "DFKI_COLUMNS",
           "KAHEMAN_TRIPLE_FILE", "KAHEMAN_TRIPLE_PARAMETERS_FILE", "kaheman_published_chain",
           "kaheman_published_parameters", "dfki_lab_parameters", "dfki_lab_values",
           "read_dfki_lab_values", "dfki_parameters", "write_dfki_lab_parameters",
           "TIME_UNITS", "DFKI_KEYS", "CHECKS"]

#: Fewest samples a piece may have.
MIN_SAMPLES = 10
#: A time step longer than this many median steps is a gap: the piece is cut there.
GAP_FACTOR = 5.0
#: Largest fraction of rows holding NaN or inf that a reader drops (counted); above it, refused.
NONFINITE = 0.05
#: The free-swing data file of Kaheman et al. (2023) in ``data/kaheman2023/``.
KAHEMAN_FILE = "DoublePendulumDataForParameterEstimation.mat"
#: The authors' identified parameters beside it (:func:`kaheman_published_parameters`).
KAHEMAN_PARAMETERS_FILE = "EstimatedParameters_DoublePendulum.mat"
#: The free-swing triple pendulum's data file (the same rig with a third arm) in ``data/kaheman2023-triple/``.
KAHEMAN_TRIPLE_FILE = "TriplePendulumDataForParameterEstimation.mat"
#: The authors' identified parameters of the triple pendulum (:func:`kaheman_published_chain`).
KAHEMAN_TRIPLE_PARAMETERS_FILE = "EstimatedParameters_TriplePendulum.mat"
#: The columns :meth:`Measurements.from_dfki` reads (``filtered=True`` takes ``pos_filt``/``vel_filt``).
DFKI_COLUMNS = {"t": "time", "phi": "pos_meas1", "psi": "pos_meas2", "dphi": "vel_meas1", "dpsi": "vel_meas2",
                **dict(zip(TORQUE_NAMES, ("tau_meas1", "tau_meas2")))}

#: The keys of a recording's columns: time, angles, speeds and the joint torques (the model's ``tau1, tau2``).
_COLUMN_KEYS = ("t", "phi", "psi", "dphi", "dpsi") + TORQUE_NAMES
#: The units of a file's time column a :class:`Convention` may state, in seconds.
TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6}
_CHECKS = ("mean", "tracking", "velocities", "units")
#: The reader checks that ``skip=`` may leave out (the heuristic ones).
CHECKS = _CHECKS


# -- conventions --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Convention:
    """How a file measures its angles (and the torques that go with them).

    * ``second``: ``"relative"`` (the second angle is measured from rod 1, as skewpend's ``psi``;
      every later angle from the rod before) or ``"absolute"`` (from the vertical, like the first);
    * ``zero``: ``"hanging"`` (0 with the rods hanging, as skewpend) or ``"upright"`` (0 with the
      rods up; hanging is pi) -- it applies to absolute angles (a relative angle is 0 with the rods
      in line either way);
    * ``sign``: per angle, +1 when the file's angle turns the same way as skewpend's (about the
      hinge axis, right-handed), -1 when it turns the other way; a joint torque takes its angle's
      sign; ``(1, 1)`` (the default) keeps every angle's sense for any number of angles, otherwise
      one sign per angle;
    * ``unit``: ``"rad"`` or ``"deg"`` (angles and angular speeds; torques are always N m);
    * ``wrapped``: the file's angles are reduced into one turn (jumps of 2 pi where they pass the
      cut); the readers unwrap them.  Without it such jumps are refused.
    * ``time``: the unit of the file's time column, ``"s"`` (default), ``"ms"`` or ``"us"``; the
      readers scale it to seconds (speeds stay per second).
    """

    second: str = "relative"
    zero: str = "hanging"
    sign: Tuple[int, int] = (1, 1)
    unit: str = "rad"
    wrapped: bool = False
    time: str = "s"

    def __post_init__(self):
        for key, (a, b) in (("second", ("relative", "absolute")), ("zero", ("hanging", "upright")),
                            ("unit", ("rad", "deg"))):
            if getattr(self, key) not in (a, b):
                raise ParameterError(f"Convention {key} must be {a!r} or {b!r}, got {getattr(self, key)!r}",
                                     parameter="convention")
        if self.time not in TIME_UNITS:
            raise ParameterError(f"Convention time must be one of {', '.join(map(repr, TIME_UNITS))}, got {self.time!r}",
                                 parameter="convention")
        try:
            sign = tuple(int(s) for s in self.sign)
        except (TypeError, ValueError):
            sign = ()
        if len(sign) < 2 or any(s not in (1, -1) for s in sign) or any(s != x for s, x in zip(sign, self.sign)):
            raise ParameterError(f"Convention sign must be +1/-1 per angle (two or more), got {self.sign!r}",
                                 parameter="convention")
        object.__setattr__(self, "sign", sign)
        object.__setattr__(self, "wrapped", bool(self.wrapped))

    @property
    def scale(self) -> float:
        """Radians per unit of the file's angles."""
        return math.pi / 180.0 if self.unit == "deg" else 1.0

    @property
    def period(self) -> float:
        """One turn in the file's unit."""
        return 360.0 if self.unit == "deg" else 2 * math.pi

    @property
    def seconds(self) -> float:
        """Seconds per unit of the file's time column."""
        return TIME_UNITS[self.time]

    def signs(self, n: int) -> np.ndarray:
        """The sign of each of ``n`` angles (one line when the convention gives another number)."""
        if all(s == 1 for s in self.sign):
            return np.ones(n)
        if len(self.sign) != n:
            raise ParameterError(f"Convention sign gives {len(self.sign)} signs for {n} angles: give one sign per angle",
                                 parameter="convention")
        return np.asarray(self.sign, dtype=float)

    def to_dict(self) -> Dict[str, Any]:
        return {"second": self.second, "zero": self.zero, "sign": list(self.sign), "unit": self.unit,
                "wrapped": self.wrapped, "time": self.time}

    def describe(self, n: int = 2) -> str:
        """The conversion of ``n`` angles to skewpend's coordinates as formulas (``theta1``, ``theta2``
        the file's angles), e.g. ``phi = theta1 - pi, psi = theta2 - theta1``."""
        k = " * pi/180" if self.unit == "deg" else ""
        signs = self.signs(n)
        th = [("-" if signs[i] < 0 else "") + f"theta{i + 1}{k}" for i in range(n)]
        parts = [th[0] + (" - pi" if self.zero == "upright" else "")]
        for i in range(1, n):
            prev = f"({th[i - 1]})" if th[i - 1].startswith("-") else th[i - 1]
            parts.append(f"{th[i]} - {prev}" if self.second == "absolute" else th[i])
        text = ", ".join(f"{name} = {x}" for name, x in zip(coordinate_names(n), parts))
        if np.any(signs < 0):
            text += "; torques times " + ", ".join(f"{int(x):+d}" for x in signs)
        if self.time != "s":
            text += f"; t = time * {self.seconds:g} s (the file's time in {self.time})"
        return text + (" (unwrapped first)" if self.wrapped else "")


#: skewpend's own convention: relative second angle, zero hanging, radians, same sense.
SKEWPEND = Convention()


def convert(q, dq=None, u=None, *, convention: Convention = SKEWPEND):
    """The file's angles ``q`` (n x 2), speeds ``dq`` and torques ``u`` in ``convention`` ->
    skewpend's ``(q, dq, u)`` (``None`` stays ``None``).  Affine and exactly invertible by
    :func:`convert_back` (to rounding); unwrapping and the whole-turn shifts of the readers are
    not part of it.

    Absolute angles from the upright (the Kaheman rig's), rod 1 0.1 rad and rod 2 0.3 rad past
    hanging, are ``phi = 0.1``, ``psi = 0.2``:

    >>> from math import pi
    >>> q, dq, u = convert([[pi + 0.1, pi + 0.3]], convention=Convention(second="absolute", zero="upright"))
    >>> [round(float(x), 12) for x in q[0]], dq, u
    ([0.1, 0.2], None, None)
    """
    c = convention
    q = np.asarray(q, dtype=float)
    sign = c.signs(q.shape[1])
    a = q * c.scale * sign
    if c.zero == "upright":
        a[:, 0 if c.second == "relative" else slice(None)] -= math.pi
    if c.second == "absolute":  # each angle from the rod before: differences of the absolute ones
        a[:, 1:] = a[:, 1:] - a[:, :-1].copy()
    v = None
    if dq is not None:
        v = np.asarray(dq, dtype=float) * c.scale * sign
        if c.second == "absolute":
            v[:, 1:] = v[:, 1:] - v[:, :-1].copy()
    w = None if u is None else np.asarray(u, dtype=float) * sign
    return a, v, w


def convert_back(q, dq=None, u=None, *, convention: Convention = SKEWPEND):
    """Inverse of :func:`convert`: skewpend's ``(q, dq, u)`` -> the file's, in ``convention``."""
    c = convention
    a = np.array(q, dtype=float)
    sign = c.signs(a.shape[1])
    if c.second == "absolute":
        a = np.cumsum(a, axis=1)
    if c.zero == "upright":
        a[:, 0 if c.second == "relative" else slice(None)] += math.pi
    a = a * sign / c.scale
    v = None
    if dq is not None:
        v = np.array(dq, dtype=float)
        if c.second == "absolute":
            v = np.cumsum(v, axis=1)
        v = v * sign / c.scale
    w = None if u is None else np.asarray(u, dtype=float) * sign
    return a, v, w


# -- one piece ----------------------------------------------------------------------------------------
def _frozen(x: Optional[np.ndarray]) -> Optional[np.ndarray]:
    if x is None:
        return None
    x = np.array(x, dtype=float)
    x.flags.writeable = False
    return x


@dataclass(frozen=True, eq=False)
class Piece:
    """One stretch of contiguous samples, in skewpend's coordinates: ``t`` (n,) [s], strictly
    increasing, steps possibly uneven; ``q`` (n, k) the k angles ``(phi, psi)`` of the double pendulum,
    ``q1`` to ``qk`` of a chain [rad]; ``dq`` (n, k) [rad/s] or None (not measured); ``u`` (n, k) joint
    torques [N m] or None (not measured; a free swing);
    ``name``, ``source`` (the file), ``group`` (``"fit"``/``"validation"`` where the file says),
    ``note`` (what was done to it: cut at a gap, ...).  Arrays are read-only."""

    t: np.ndarray
    q: np.ndarray
    dq: Optional[np.ndarray] = None
    u: Optional[np.ndarray] = None
    name: str = ""
    source: str = ""
    group: str = ""
    note: str = ""

    def __post_init__(self):
        for key in ("t", "q", "dq", "u"):
            object.__setattr__(self, key, _frozen(getattr(self, key)))

    def __len__(self) -> int:
        return len(self.t)

    @property
    def duration(self) -> float:
        return float(self.t[-1] - self.t[0])

    @property
    def dt(self) -> float:
        """The median time step [s]."""
        return float(np.median(np.diff(self.t)))

    @property
    def nq(self) -> int:
        """The number of angles (2 for the double pendulum, a chain's links)."""
        return int(self.q.shape[1])

    @property
    def y(self) -> Optional[np.ndarray]:
        """States ``(q, q')`` (n, 2 k; ``(phi, psi, dphi, dpsi)`` for two angles), or None without measured speeds."""
        return None if self.dq is None else np.hstack([self.q, self.dq])

    def sampling(self) -> Dict[str, Any]:
        d = np.diff(self.t)
        return {"name": self.name, "group": self.group, "samples": len(self), "start": float(self.t[0]),
                "duration": self.duration, "median_dt": float(np.median(d)), "min_dt": float(d.min()),
                "max_dt": float(d.max()), "note": self.note}

    def line(self) -> str:
        """One line: name, samples, duration, steps, and what was done to it."""
        s = self.sampling()
        group = f" ({self.group})" if self.group else ""
        steps = (f"dt {s['median_dt']:.4g} s" if s["max_dt"] - s["min_dt"] <= 1e-6 * s["median_dt"]
                 else f"median dt {s['median_dt']:.4g} s ({s['min_dt']:.3g}..{s['max_dt']:.3g})")
        return (f"{self.name}{group}: {len(self)} samples, {self.duration:.4g} s from t = {self.t[0]:.4g} s, {steps}, "
                + (self.note or "no gaps"))

    def __repr__(self) -> str:
        have = ", ".join(k for k, v in (("speeds", self.dq), ("torques", self.u)) if v is not None) or "angles only"
        return f"<Piece {self.line()}; {have}>"

    def _take(self, rows, **changes) -> "Piece":
        values = {"t": self.t[rows], "q": self.q[rows], "dq": None if self.dq is None else self.dq[rows],
                  "u": None if self.u is None else self.u[rows], "name": self.name, "source": self.source,
                  "group": self.group, "note": self.note}
        values.update(changes)
        return Piece(**values)


# -- checks -------------------------------------------------------------------------------------------
def _as_pairs(value, n: int, what: str, label: str, k: Optional[int] = None) -> Optional[np.ndarray]:
    """``value`` as an (n, k) array: n samples like the times, k angles (``k`` None: the angles' own,
    two or more)."""
    if value is None:
        return None
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ParameterError(f"{label}: {what} must be numbers") from None
    if k is None:
        if a.ndim != 2 or a.shape[0] != n or a.shape[1] < 2:
            raise ParameterError(f"{label}: {what} must have shape ({n}, k) like the times, k >= 2 angles, got {a.shape}")
    elif a.shape != (n, k):
        raise ParameterError(f"{label}: {what} must have shape ({n}, {k}) like the times and the {k} angles, "
                             f"got {a.shape}")
    return a


class _Builder:
    """Checks and converts raw pieces; collects what it did (``actions``)."""

    def __init__(self, convention: Convention, source: str, *, nonfinite: float, gap_factor: float,
                 min_duration: float, short: str, skip: Sequence[str]):
        if not isinstance(convention, Convention):
            raise ParameterError(f"convention must be a skewpend.Convention, got {type(convention).__name__}",
                                 parameter="convention")
        if not (isinstance(nonfinite, (int, float)) and 0 <= nonfinite < 1):
            raise ParameterError(f"nonfinite must be a fraction in [0, 1), got {nonfinite!r}", parameter="nonfinite")
        if not (isinstance(gap_factor, (int, float)) and gap_factor > 1 and math.isfinite(gap_factor)):
            raise ParameterError(f"gap_factor must be a number above 1, got {gap_factor!r}", parameter="gap_factor")
        if not (isinstance(min_duration, (int, float)) and min_duration >= 0 and math.isfinite(min_duration)):
            raise ParameterError(f"min_duration must be a number of seconds >= 0, got {min_duration!r}",
                                 parameter="min_duration")
        if short not in ("refuse", "drop"):
            raise ParameterError(f"short must be 'refuse' or 'drop', got {short!r}", parameter="short")
        skip = (skip,) if isinstance(skip, str) else tuple(skip)
        unknown = [s for s in skip if s not in _CHECKS]
        if unknown:
            raise ParameterError(f"skip: unknown check {unknown[0]!r}; the checks that may be skipped: "
                                 f"{', '.join(_CHECKS)}", parameter="skip")
        self.convention, self.source = convention, source
        self.nonfinite, self.gap_factor, self.min_duration, self.short, self.skip = (
            float(nonfinite), float(gap_factor), float(min_duration), short, skip)
        self.actions: List[str] = []

    def settings(self) -> Dict[str, Any]:
        return {"nonfinite": self.nonfinite, "gap_factor": self.gap_factor, "min_duration": self.min_duration,
                "min_samples": MIN_SAMPLES, "short": self.short, "skip": list(self.skip)}

    def build(self, raw: Mapping[str, Any]) -> List[Piece]:
        name = str(raw.get("name") or "piece")
        source = str(raw.get("source") or self.source)
        label = f"{Path(source).name}: {name}" if source else name
        try:
            t = np.asarray(raw["t"], dtype=float).ravel() * self.convention.seconds
            q_raw = np.asarray(raw["q"], dtype=float)
        except KeyError as exc:
            raise ParameterError(f"{label}: a piece needs {exc.args[0]!r}") from None
        except (TypeError, ValueError):
            raise ParameterError(f"{label}: times and angles must be numbers") from None
        n = len(t)
        q = _as_pairs(q_raw, n, "angles q", label)
        assert q is not None
        dq = _as_pairs(raw.get("dq"), n, "speeds dq", label, q.shape[1])
        u = _as_pairs(raw.get("u"), n, "torques u", label, q.shape[1])
        # NaN / inf rows
        good = np.isfinite(t) & np.isfinite(q).all(axis=1)
        for x in (dq, u):
            if x is not None:
                good &= np.isfinite(x).all(axis=1)
        bad = int(n - good.sum())
        if bad:
            if bad > self.nonfinite * n:
                raise ParameterError(f"{label}: {bad} of {n} rows hold NaN or inf ({bad / n:.1%}), more than "
                                     f"nonfinite={self.nonfinite:g} allows: clean the data or raise nonfinite")
            t, q, dq, u = (None if x is None else x[good] for x in (t, q, dq, u))
            self.actions.append(f"{label}: dropped {bad} of {n} rows holding NaN or inf")
        if len(t) < MIN_SAMPLES:
            raise ParameterError(f"{label}: {len(t)} samples; a piece needs at least {MIN_SAMPLES}")
        steps = np.diff(t)
        if np.any(steps <= 0):
            i = int(np.argmax(steps <= 0))
            raise ParameterError(f"{label}: time does not increase at sample {i + 1} (counting from 0; t = {t[i]:.9g} then "
                                 f"{t[i + 1]:.9g}): sort the rows, or cut the data into pieces where time restarts")
        # gaps
        median = float(np.median(steps))
        cuts = np.flatnonzero(steps > self.gap_factor * median)
        bounds = [0, *(cuts + 1).tolist(), len(t)]
        if len(cuts):
            where = ", ".join(f"{t[i]:.6g}..{t[i + 1]:.6g} s" for i in cuts[:5]) + (", ..." if len(cuts) > 5 else "")
            self.actions.append(f"{label}: cut into {len(cuts) + 1} pieces at {len(cuts)} gap(s) longer than "
                                f"{self.gap_factor:g} x the median step {median:.4g} s ({where})")
        pieces = []
        for k in range(len(bounds) - 1):
            rows = slice(bounds[k], bounds[k + 1])
            sub = name if len(cuts) == 0 else f"{name} part {k + 1}"
            note = "" if len(cuts) == 0 else f"part {k + 1} of {len(cuts) + 1}, cut at gaps"
            sub_label = f"{Path(source).name}: {sub}" if source else sub
            ts = t[rows]
            if len(ts) < MIN_SAMPLES or ts[-1] - ts[0] < self.min_duration:
                why = (f"{len(ts)} samples (fewer than {MIN_SAMPLES})" if len(ts) < MIN_SAMPLES else
                       f"{ts[-1] - ts[0]:.4g} s (shorter than min_duration={self.min_duration:g} s)")
                if self.short == "drop":
                    self.actions.append(f"{sub_label}: dropped, {why}")
                    continue
                raise ParameterError(f"{sub_label}: {why}" + (" after cutting at gaps" if len(cuts) else "")
                                     + "; pass short='drop' to drop such pieces (recorded in metadata)")
            piece = self._convert(ts, q[rows], None if dq is None else dq[rows], None if u is None else u[rows],
                                  sub_label)
            pieces.append(Piece(t=ts, q=piece[0], dq=piece[1], u=piece[2], name=sub, source=source,
                                group=str(raw.get("group") or ""), note=note))
        return pieces

    def _convert(self, t, q, dq, u, label):
        c = self.convention
        q = np.array(q, dtype=float)
        if "units" not in self.skip:  # before the wraps: degrees read as radians jump like wrapped angles
            self._check_units_raw(q, label)
        jumps = np.abs(np.diff(q, axis=0)) > c.period / 2
        if jumps.any():
            count = int(jumps.sum())
            if not c.wrapped:
                i, k = np.argwhere(jumps)[0]
                raise ParameterError(
                    f"{label}: the {_ordinal(k)} angle jumps by {q[i + 1, k] - q[i, k]:+.4g} {c.unit} between samples at "
                    f"t = {t[i]:.6g} s ({count} such jumps): the angles look wrapped into one turn; state "
                    "Convention(wrapped=True) to unwrap them")
            q = np.unwrap(q, axis=0, period=c.period)
            self.actions.append(f"{label}: unwrapped {count} jump(s) of one turn")
        q, dq, u = convert(q, dq, u, convention=c)
        angles = coordinate_names(q.shape[1])
        for k, name in enumerate(angles):
            turns = round(float(np.median(q[:, k])) / (2 * math.pi))
            if turns:
                q[:, k] -= 2 * math.pi * turns
                self.actions.append(f"{label}: {name} shifted by {-turns:+d} turn(s) to put its median in (-pi, pi]")
        for k, name in enumerate(angles):
            x = q[:, k]
            if np.ptp(x) <= 1e-12 * max(1.0, float(np.abs(x).max())):
                raise ParameterError(f"{label}: {name} is constant ({x[0]:.6g} rad) over the piece: a measurement "
                                     "needs motion; drop the piece or check the column mapping")
        if dq is not None and "velocities" not in self.skip:
            self._check_velocities(t, q, dq, label)
        if u is None and "mean" not in self.skip:
            self._check_mean(q, label)
        if c.second == "relative" and "tracking" not in self.skip:
            self._check_tracking(q, label)
        return q, dq, u

    def _check_units_raw(self, q, label):
        """The angles' unit, on the numbers as written (before unwrapping, conversion, shifting): radians
        that swing back and forth over more than two turns look like degrees; degrees that stay within
        one radian's turn (|x| <= 2 pi) while swinging back and forth over at least
        :data:`RADIAN_SWING` look like radians."""
        c = self.convention
        for k, name in enumerate(coordinate_names(q.shape[1])):
            x = q[:, k]
            crossings = int(np.count_nonzero(np.diff(np.sign(x - x.mean())) != 0))
            if crossings < 4:
                continue
            turns = _reversals(x, 2 * math.pi) if c.unit == "rad" else 0
            if c.unit == "rad" and turns >= 4:
                raise ParameterError(
                    f"{label}: {name} swings back and forth over {np.ptp(x):.3g} rad, {turns} times by more than a "
                    "turn between its turning points: the angles look like degrees; state "
                    "Convention(unit='deg'), or skip=('units',) if the rig really turns over and back")
            if c.unit == "deg" and float(np.abs(x).max()) <= 2 * math.pi and np.ptp(x) >= RADIAN_SWING:
                raise ParameterError(
                    f"{label}: {name} swings back and forth between {x.min():.3g} and {x.max():.3g} (read as degrees: "
                    f"a swing of {np.ptp(x):.2g} deg, within one radian's turn): the angles look like radians; state "
                    "Convention(unit='rad'), or skip=('units',) if the rig really swings by so little")

    def _check_velocities(self, t, q, dq, label):
        for k, name in enumerate(coordinate_names(q.shape[1])):
            rate = np.gradient(q[:, k], t)
            if np.std(rate) == 0 or np.std(dq[:, k]) == 0:
                continue
            r = float(np.corrcoef(rate, dq[:, k])[0, 1])
            ratio = float(np.std(dq[:, k]) / np.std(rate))
            if r < -0.5:
                raise ParameterError(f"{label}: d{name} runs against {name}'s rate of change (correlation {r:.2f}): "
                                     "its sign or its column is wrong; check the column mapping, or skip=('velocities',)")
            if -0.5 <= r <= 0.5:
                raise ParameterError(f"{label}: d{name} does not follow {name}'s rate of change (correlation {r:.2f}): "
                                     "the speeds look of another column, or shifted in time; check the column "
                                     "mapping, or skip=('velocities',)")
            if r > 0.5 and not (1 / 3 < ratio < 3):
                raise ParameterError(f"{label}: d{name} is {ratio:.3g} times {name}'s rate of change: the speeds look "
                                     "in other units than the angles (degrees?) or of another column; check the "
                                     "mapping, or skip=('velocities',)")

    def _check_mean(self, q, label):
        c = self.convention
        for k, name in enumerate(coordinate_names(q.shape[1])):
            x = q[:, k]
            if np.ptp(x) >= 2 * math.pi:  # turns over: no mean to judge
                continue
            m = float(np.mean(x))
            if abs(m) <= math.pi / 2:
                continue
            if k == 0:
                raw = convert_back(q, convention=c)[0]
                if c.unit == "deg" and np.all(np.abs(raw) <= 2 * math.pi):  # numbers within one radian's turn ...
                    q_rad = convert(raw, convention=replace(c, unit="rad"))[0]
                    if np.all(np.abs(np.mean(q_rad, axis=0)) <= math.pi / 2):  # ... that swing about hanging as radians
                        raise ParameterError(
                            f"{label}: a free swing's phi has mean {m:.3g} rad, near the upright, not the hanging rest "
                            f"it swings about, as degrees; its numbers stay within one radian's turn and, read as "
                            "radians, swing about the hanging rest: the angles look like radians; state "
                            "Convention(unit='rad')")
                other = "upright" if c.zero == "hanging" else "hanging"
                raise ParameterError(
                    f"{label}: a free swing's phi has mean {m:.3g} rad, near the upright, not the hanging rest "
                    f"it swings about: the data look measured with zero {other}; state Convention(zero={other!r}), "
                    "or skip=('mean',) if the rig really swings about the top")
            other = "absolute" if c.second == "relative" else "relative"
            raise ParameterError(
                f"{label}: a free swing's {name} has mean {m:.3g} rad, near rod {k + 1} folded up, not about any rest "
                f"of a free swing: the second angle looks {other} (or zeroed the other way); state "
                f"Convention(second={other!r}) or check zero=, or skip=('mean',)")

    def _check_tracking(self, q, label):
        names = coordinate_names(q.shape[1])
        for k in range(1, q.shape[1]):
            one, two = q[:, k - 1], q[:, k]
            if np.std(one) == 0 or np.std(two) == 0:
                continue
            r = float(np.corrcoef(one, two)[0, 1])
            ratio = float(np.std(two - one) / np.std(one))
            if r > 0.95 and ratio < 0.25:
                a, b = names[k - 1], names[k]
                raise ParameterError(
                    f"{label}: {b} follows {a} (correlation {r:.3f}; {b} - {a} varies {ratio:.2g} times as much as {a}), "
                    "as an absolute angle does: state Convention(second='absolute'), or skip=('tracking',) "
                    f"if rod {k + 1} really turns about twice as far as rod {k}")


#: Degrees that stay within +-2 pi and swing back and forth over at least this many (as numbers) look
#: like radians (a swing of 0.5 rad is a real one; of 0.5 deg, hardly a recording to identify from).
RADIAN_SWING = 0.5


def _reversals(x: np.ndarray, h: float) -> int:
    """How many times ``x`` turns back after moving more than ``h`` from its last turning point (a
    zigzag with threshold ``h``: noise and smaller swings do not count)."""
    values = np.asarray(x, float)[:: max(1, len(x) // 20000)]
    count, direction = 0, 0
    lo = hi = ext = float(values[0])
    for v in values:
        if direction == 0:
            lo, hi = min(lo, v), max(hi, v)
            if v > lo + h:
                direction, ext = 1, v
            elif v < hi - h:
                direction, ext = -1, v
        elif direction > 0:
            if v > ext:
                ext = v
            elif v < ext - h:
                count, direction, ext = count + 1, -1, v
        else:
            if v < ext:
                ext = v
            elif v > ext + h:
                count, direction, ext = count + 1, 1, v
    return count


def _ordinal(k: int) -> str:
    """``0 -> "first"``, ``1 -> "second"``, ... (an angle's place)."""
    words = ("first", "second", "third", "fourth", "fifth", "sixth", "seventh", "eighth")
    return words[k] if k < len(words) else f"{k + 1}th"


# -- the measurements ---------------------------------------------------------------------------------
def _plain_freeze(value):
    if isinstance(value, Mapping):
        return MappingProxyType({k: _plain_freeze(v) for k, v in value.items()})
    if isinstance(value, (list, tuple)):
        return tuple(_plain_freeze(v) for v in value)
    return value


@dataclass(frozen=True, eq=False)
class Measurements:
    """Measured motion in skewpend's coordinates: ``pieces`` (a tuple of :class:`Piece`) and
    ``metadata`` (read-only: ``format``, ``sources``, ``convention`` as stated, ``conversion``
    as formulas, ``checks`` (their settings), ``actions`` (everything done to the data: rows
    dropped, pieces cut at gaps, angles unwrapped or shifted by whole turns, splits),
    ``sampling`` (per piece: samples, start, duration, median/min/max step)).

    Build one with a reader (:meth:`from_kaheman`, :meth:`from_dfki`, :meth:`from_csv`,
    :meth:`from_mat`, :meth:`from_trajectory`) or :meth:`from_arrays`.  ``len()`` counts pieces;
    indexing takes a piece by position or name; :meth:`split` makes fitting and held-out sets,
    :meth:`select` a subset, :meth:`summary` one line per piece.
    """

    pieces: Tuple[Piece, ...]
    metadata: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self):
        pieces = tuple(self.pieces)
        if not pieces or not all(isinstance(p, Piece) for p in pieces):
            raise ParameterError("Measurements need at least one Piece")
        if len({p.nq for p in pieces}) > 1:
            raise ParameterError("Measurements' pieces must all have the same number of angles, got "
                                 + ", ".join(str(n) for n in sorted({p.nq for p in pieces})))
        object.__setattr__(self, "pieces", pieces)
        meta = dict(self.metadata)
        meta["sampling"] = [p.sampling() for p in pieces]
        object.__setattr__(self, "metadata", _plain_freeze(meta))

    # -- a sequence of pieces ------------------------------------------------------------------------
    def __len__(self) -> int:
        return len(self.pieces)

    def __iter__(self) -> Iterator[Piece]:
        return iter(self.pieces)

    def __getitem__(self, key: Union[int, str]) -> Piece:
        if isinstance(key, str):
            for p in self.pieces:
                if p.name == key:
                    return p
            raise KeyError(key)
        return self.pieces[key]

    @property
    def names(self) -> Tuple[str, ...]:
        return tuple(p.name for p in self.pieces)

    @property
    def nq(self) -> int:
        """The number of angles each piece holds (2: the double pendulum; a chain's links)."""
        return self.pieces[0].nq

    @property
    def coordinates(self) -> Tuple[str, ...]:
        """The angles' names (``phi``, ``psi``; ``q1`` to ``qk`` for another number)."""
        return coordinate_names(self.nq)

    @property
    def samples(self) -> int:
        """Samples in all pieces together."""
        return sum(len(p) for p in self.pieces)

    @property
    def duration(self) -> float:
        """Measured time in all pieces together [s]."""
        return sum(p.duration for p in self.pieces)

    @property
    def has_velocities(self) -> bool:
        return all(p.dq is not None for p in self.pieces)

    @property
    def has_torques(self) -> bool:
        return all(p.u is not None for p in self.pieces)

    def _groups(self) -> str:
        counts = Counter(p.group for p in self.pieces if p.group)
        return f" ({', '.join(f'{g} {n}' for g, n in counts.items())})" if counts else ""

    def __repr__(self) -> str:
        sources = self.metadata.get("sources", ())
        src = Path(sources[0]).name + (f" and {len(sources) - 1} more" if len(sources) > 1 else "") if sources else ""
        speeds = "speeds" if self.has_velocities else ("some speeds" if any(p.dq is not None for p in self) else
                                                       "no speeds")
        torques = "torques" if self.has_torques else ("some torques" if any(p.u is not None for p in self) else
                                                      "no torques")
        return (f"<Measurements {self.metadata.get('format', '')}: {len(self)} pieces{self._groups()}, "
                f"{self.samples} samples over {self.duration:.4g} s; {speeds}, {torques}"
                + (f"; from {src}" if src else "") + ">")

    def summary(self) -> str:
        """A line for the whole, a line per piece, then the conversion and every action taken."""
        lines = [repr(self)[1:-1], f"conversion: {self.metadata.get('conversion', '')}"]
        lines += [p.line() for p in self.pieces]
        lines += [f"done: {a}" for a in self.metadata.get("actions", ())]
        return "\n".join(lines)

    def _with(self, pieces: Sequence[Piece], action: str) -> "Measurements":
        meta = {k: v for k, v in self.metadata.items() if k != "sampling"}
        meta["actions"] = list(meta.get("actions", ())) + [action]
        return Measurements(pieces=tuple(pieces), metadata=_thaw(meta))

    # -- subsets -------------------------------------------------------------------------------------
    def _indices(self, which) -> List[int]:
        if isinstance(which, (int, np.integer, str)):
            which = [which]
        out = []
        for w in which:
            if isinstance(w, str):
                if w not in self.names:
                    raise ParameterError(f"no piece named {w!r}; the pieces: {', '.join(self.names[:8])}"
                                         + (", ..." if len(self) > 8 else ""))
                out.append(self.names.index(w))
            elif isinstance(w, (int, np.integer)) and not isinstance(w, bool) and -len(self) <= w < len(self):
                out.append(int(w) % len(self))
            else:
                raise ParameterError(f"piece {w!r} is not a piece's index (0..{len(self) - 1}) or name")
        return out

    def select(self, pieces=None, *, group: Optional[str] = None,
               time: Optional[Tuple[float, float]] = None) -> "Measurements":
        """The pieces given (indices or names, one or several), of a ``group`` (``"fit"``,
        ``"validation"``), and/or only their samples with ``time[0] <= t <= time[1]`` (pieces
        left with fewer than :data:`MIN_SAMPLES` samples in that window are dropped, recorded)."""
        chosen = list(range(len(self))) if pieces is None else self._indices(pieces)
        if group is not None:
            chosen = [i for i in chosen if self.pieces[i].group == group]
        what = []
        if pieces is not None:
            what.append(f"pieces {', '.join(self.pieces[i].name for i in chosen)}")
        if group is not None:
            what.append(f"group {group!r}")
        result = [self.pieces[i] for i in chosen]
        if time is not None:
            try:
                t0, t1 = (float(x) for x in time)
            except (TypeError, ValueError):
                raise ParameterError(f"time must be a pair (start, end) in seconds, got {time!r}") from None
            if not t0 < t1:
                raise ParameterError(f"time must be a pair (start, end) with start < end, got {time!r}")
            windowed, dropped = [], []
            for p in result:
                rows = (p.t >= t0) & (p.t <= t1)
                if rows.sum() >= MIN_SAMPLES:
                    windowed.append(p if rows.all() else p._take(rows))
                else:
                    dropped.append(p.name)
            result = windowed
            what.append(f"time {t0:g}..{t1:g} s" + (f" (dropped {len(dropped)} piece(s) with fewer than "
                                                    f"{MIN_SAMPLES} samples in it)" if dropped else ""))
        if not result:
            raise ParameterError(f"select({', '.join(what) or 'nothing'}) leaves no piece")
        return self._with(result, "selected " + "; ".join(what or ["all"]))

    def split(self, held_out: Union[float, str, Sequence[Union[int, str]]] = 0.25
              ) -> Tuple["Measurements", "Measurements"]:
        """``(fit, held_out)`` for validation.  ``held_out``:

        * a group name (``"validation"``): its pieces are held out (the file's own split);
        * indices or names of pieces;
        * a fraction in (0, 1): that share of the pieces, the last ones (the later in the file),
          at least one on each side; a single piece is cut in time instead (its last ``fraction``
          held out).
        """
        n = len(self)
        if isinstance(held_out, str) and held_out not in self.names:
            held = [i for i, p in enumerate(self.pieces) if p.group == held_out]
            if not held:
                groups = sorted({p.group for p in self.pieces if p.group})
                raise ParameterError(f"no piece is in group {held_out!r}"
                                     + (f"; the groups: {', '.join(groups)}" if groups else "; no piece has a group"))
            how = f"group {held_out!r} held out"
        elif isinstance(held_out, (float, np.floating)) and not isinstance(held_out, bool):
            f = float(held_out)
            if not 0 < f < 1:
                raise ParameterError(f"held_out as a fraction must be in (0, 1), got {held_out!r}", parameter="held_out")
            if n == 1:
                p = self.pieces[0]
                cut = int(np.searchsorted(p.t, p.t[0] + (1 - f) * p.duration))
                if cut < MIN_SAMPLES or len(p) - cut < MIN_SAMPLES:
                    raise ParameterError(f"{p.name}: cutting at {1 - f:.0%} of its time leaves fewer than "
                                         f"{MIN_SAMPLES} samples on one side; choose another fraction")
                a = p._take(slice(0, cut), name=f"{p.name} (fit part)")
                b = p._take(slice(cut, None), name=f"{p.name} (held-out part)")
                how = f"{p.name} cut at t = {p.t[cut]:.6g} s, the last {f:.0%} of its time held out"
                return self._with([a], f"split: {how}"), self._with([b], f"split: {how}")
            k = min(n - 1, max(1, round(f * n)))
            held = list(range(n - k, n))
            how = f"the last {k} of {n} pieces held out"
        else:
            held = self._indices(held_out)
            how = f"pieces {', '.join(self.pieces[i].name for i in held)} held out"
        fit = [p for i, p in enumerate(self.pieces) if i not in held]
        if not fit:
            raise ParameterError(f"split: {how} leaves no piece to fit")
        return (self._with(fit, f"split: {how}"), self._with([self.pieces[i] for i in held], f"split: {how}"))

    def cut(self, seconds: float) -> "Measurements":
        """Every piece cut into consecutive pieces of about ``seconds`` each (a piece's duration
        divided into ``round(duration / seconds)`` equal parts, at least one; neighbours share their
        boundary sample), named ``"NAME [k]"``.  Used for held-out prediction over a fixed horizon:
        each part is simulated from its own first measured state."""
        from ..checks import positive

        seconds = positive("seconds", seconds, cap=1e6)
        out = []
        for p in self.pieces:
            # at most one part per sample (the parts of a tiny horizon are all dropped below anyway)
            count = min(max(1, int(round(p.duration / seconds))), len(p))
            if count == 1:
                out.append(p)
                continue
            edges = np.searchsorted(p.t, p.t[0] + p.duration * np.arange(count + 1) / count)
            edges[-1] = len(p) - 1
            for k in range(count):
                rows = slice(int(edges[k]), int(edges[k + 1]) + 1)
                if rows.stop - rows.start >= MIN_SAMPLES:
                    out.append(p._take(rows, name=f"{p.name} [{k}]"))
        if not out:
            raise ParameterError(f"cut({seconds:g}) leaves no piece of {MIN_SAMPLES} samples or more")
        return self._with(out, f"cut into pieces of about {seconds:g} s")

    # -- readers -------------------------------------------------------------------------------------
    @classmethod
    def from_arrays(cls, pieces: Sequence[Mapping[str, Any]], *, convention: Convention = SKEWPEND,
                    source: str = "", format: str = "arrays", nonfinite: float = NONFINITE,
                    gap_factor: float = GAP_FACTOR, min_duration: float = 0.0, short: str = "refuse",
                    skip: Sequence[str] = (), extra: Optional[Mapping[str, Any]] = None) -> "Measurements":
        """Measurements from raw pieces, each a mapping with ``t``, ``q`` (the file's two angles,
        n x 2, in ``convention``), optionally ``dq``, ``u``, ``name``, ``group``, ``source``.
        Every reader ends here: it converts to skewpend's coordinates and runs the checks (see
        the module); ``skip`` names checks to leave out (``"mean"``, ``"tracking"``,
        ``"velocities"``: the heuristic ones), recorded in ``metadata["checks"]``."""
        builder = _Builder(convention, source, nonfinite=nonfinite, gap_factor=gap_factor,
                           min_duration=min_duration, short=short, skip=skip)
        if isinstance(pieces, Mapping):
            pieces = [pieces]
        built: List[Piece] = []
        for raw in pieces:
            built.extend(builder.build(raw))
        if not built:
            raise ParameterError(f"{source or 'the data'}: no piece is left after the checks (see short=)")
        if len({p.nq for p in built}) > 1:
            odd = next(p for p in built if p.nq != built[0].nq)
            raise ParameterError(f"{source or 'the data'}: pieces with different numbers of angles ({built[0].name}: "
                                 f"{built[0].nq}, {odd.name}: {odd.nq}); one recording is of one pendulum")
        sources = sorted({p.source for p in built if p.source}) or ([source] if source else [])
        meta: Dict[str, Any] = {"format": format, "sources": sources, "convention": convention.to_dict(),
                                "conversion": convention.describe(built[0].nq), "checks": builder.settings(),
                                "actions": builder.actions}
        if extra:
            meta.update(extra)
        return cls(pieces=tuple(built), metadata=meta)

    @classmethod
    def from_csv(cls, path, columns: Mapping[str, Any], *, convention: Convention = SKEWPEND,
                 delimiter: str = ",", **checks) -> "Measurements":
        """Measurements from one or more CSV files with a header line, one piece per file.
        ``columns`` maps ``t``, ``phi``, ``psi`` (required: the file's first and second angle, in
        ``convention``) and optionally ``dphi``, ``dpsi``, ``tau1``, ``tau2`` to column names;
        speeds and torques come in pairs (absent: None); a torque may be a number (``"tau2": 0.0``
        for an unactuated joint).  ``checks``: see :meth:`from_arrays`."""
        paths = _paths(path)
        raws = [_read_csv_piece(p, columns, delimiter) for p in paths]
        return cls.from_arrays(raws, convention=convention, source=str(paths[0]), format="csv", **checks)

    @classmethod
    def from_dfki(cls, path, *, filtered: bool = False, convention: Convention = SKEWPEND,
                  **checks) -> "Measurements":
        """The DFKI double-pendulum rig's CSV files (``trajectory_NN.csv``; a folder reads all of
        them): relative joint angles, zero hanging, in the sense of skewpend's (see the guide),
        measured speeds (``filtered=True``: the lab's filtered angles and speeds) and the measured
        motor torques ``tau_meas``.  The measured, uneven time steps are kept."""
        paths = _paths(path, pattern="trajectory_*.csv")
        columns = dict(DFKI_COLUMNS)
        if filtered:
            columns.update(phi="pos_filt1", psi="pos_filt2", dphi="vel_filt1", dpsi="vel_filt2")
        raws = [_read_csv_piece(p, columns, ",") for p in paths]
        return cls.from_arrays(raws, convention=convention, source=str(paths[0]), format="dfki",
                               extra={"filtered": bool(filtered)}, **checks)

    @classmethod
    def from_mat(cls, path, data: Union[str, Mapping[str, str]], time: Union[str, Mapping[str, str], None] = None,
                 *, dt: Union[float, str, None] = None, angles: Tuple[int, ...] = (0, 1),
                 velocities: Optional[Tuple[int, ...]] = None, torques: Optional[Tuple[int, ...]] = None,
                 convention: Convention = SKEWPEND, format: str = "mat", **checks) -> "Measurements":
        """Measurements from a MATLAB ``.mat`` file (v5/v7; ``scipy.io.loadmat``).  ``data`` names
        the variable holding the samples -- a cell array of pieces or one array, channels along
        one axis and samples along the other -- or maps group names to variables
        (``{"fit": "Y_id", "validation": "Y_vad"}``); ``time`` names the matching time
        variable(s), or ``dt`` gives a fixed step (a number, or a variable's name).  ``angles``,
        ``velocities``, ``torques``: the channel indices (two or more angles: a chain's; speeds and
        torques one per angle).  Pieces are named ``VAR[i]``."""
        path = Path(path)
        mat = _load_mat(path)
        groups = {"": data} if isinstance(data, str) else dict(data)
        times = time if isinstance(time, Mapping) else {g: time for g in groups}
        step: Optional[float] = None
        if dt is not None:
            try:
                step = float(np.asarray(_variable(mat, dt, path) if isinstance(dt, str) else dt).ravel()[0])
            except (TypeError, ValueError, IndexError):
                step = math.nan
            if not (math.isfinite(step) and step > 0):
                raise ParameterError(f"{path}: dt must be a positive number of seconds, got {dt!r}", parameter="dt")
        raws = []
        for group, var in groups.items():
            items = _cells(_variable(mat, var, path))
            tvar = times.get(group)
            titems = _cells(_variable(mat, tvar, path)) if tvar else [None] * len(items)
            if tvar is None and step is None:
                raise ParameterError(f"{path}: give time= (the time variable) or dt= for {var!r}", parameter="time")
            if len(titems) != len(items):
                raise ParameterError(f"{path}: {var!r} has {len(items)} pieces but {tvar!r} {len(titems)}")
            for i, (item, tv) in enumerate(zip(items, titems)):
                name = f"{var}[{i}]"
                x = np.atleast_2d(np.asarray(item, dtype=float))
                if tv is not None:
                    tt = np.asarray(tv, dtype=float).ravel()
                    if x.shape[1] != len(tt):
                        if x.shape[0] != len(tt):
                            raise ParameterError(f"{path}: {name} is {x.shape[0]} x {x.shape[1]} but its time "
                                                 f"has {len(tt)} samples")
                        x = x.T
                else:
                    x = x if x.shape[1] >= x.shape[0] else x.T
                    tt = float(step or 0.0) * np.arange(x.shape[1])
                channels = x.shape[0]
                k = len(angles)
                for what, idx in (("angles", angles), ("velocities", velocities), ("torques", torques)):
                    if idx is None:
                        continue
                    wanted = "two or more" if what == "angles" else ("two" if k == 2 else f"{k}, one per angle,")
                    if (len(idx) < 2 if what == "angles" else len(idx) != k) or not all(0 <= int(j) < channels for j in idx):
                        raise ParameterError(f"{path}: {what}={tuple(idx)!r} are not {wanted} of the {channels} channels "
                                             f"of {name}", parameter=what)
                raws.append({"t": tt, "q": x[list(angles)].T,
                             "dq": None if velocities is None else x[list(velocities)].T,
                             "u": None if torques is None else x[list(torques)].T,
                             "name": name, "group": group, "source": str(path)})
        return cls.from_arrays(raws, convention=convention, source=str(path), format=format, **checks)

    @classmethod
    def from_kaheman(cls, path, which: str = "all", **checks) -> "Measurements":
        """The free-swing double pendulum of Kaheman et al. (2023) (``data/kaheman2023/``; the
        ``.mat`` file or its folder): ``which="fit"`` (26 pieces, ``Y_id``), ``"validation"``
        (4 pieces, ``Y_vad``) or ``"all"``, grouped ``fit``/``validation``.  The file's state
        ``[theta1, theta2, dtheta1, dtheta2]`` holds absolute angles from the upright; converted:
        ``phi = theta1 - pi``, ``psi = theta2 - theta1`` (sense kept; see the guide's Conventions).

        Their triple pendulum (``TriplePendulumDataForParameterEstimation.mat``, a folder holding it:
        22 fitting and 4 validation pieces of ``[theta1, theta2, theta3, dtheta1, dtheta2, dtheta3]``)
        is read the same way, as three angles ``q1 = theta1 - pi``, ``q2 = theta2 - theta1``,
        ``q3 = theta3 - theta2``: the chain of three links."""
        path = Path(path)
        if path.is_dir():
            path = path / (KAHEMAN_TRIPLE_FILE if (path / KAHEMAN_TRIPLE_FILE).is_file() and
                           not (path / KAHEMAN_FILE).is_file() else KAHEMAN_FILE)
        layout = {"fit": ("Y_id", "Time_id"), "validation": ("Y_vad", "Time_vad")}
        if which not in ("fit", "validation", "all"):
            raise ParameterError(f"which must be 'fit', 'validation' or 'all', got {which!r}", parameter="which")
        chosen = layout if which == "all" else {which: layout[which]}
        first = _cells(_variable(_load_mat(path), "Y_id", path))[0]
        k = min(np.shape(first)) // 2  # the state holds k angles and their speeds
        if k < 2:
            raise ParameterError(f"{path}: Y_id's pieces hold {min(np.shape(first))} channels, not the angles and "
                                 "speeds of two or more arms")
        return cls.from_mat(path, {g: v[0] for g, v in chosen.items()}, {g: v[1] for g, v in chosen.items()},
                            angles=tuple(range(k)), velocities=tuple(range(k, 2 * k)), format="kaheman",
                            convention=Convention(second="absolute", zero="upright"), **checks)

    @classmethod
    def from_trajectory(cls, source, **checks) -> "Measurements":
        """skewpend's own trajectory -- a :class:`~skewpend.Trajectory` or its ``.nc``/``.csv``
        file -- as measurements: its ``t``, angles, speeds (a chain's ``n`` of each), and as torques
        the controller's plus the constant ``tau1``, ``tau2`` (a chain's joints') when there are any
        (None for a free run).  A file of a
        controlled run is refused (its torques are not stored): pass the Trajectory itself."""
        from ..numeric.simulation import Trajectory, open_trajectory

        if isinstance(source, Trajectory):
            traj, src, name = source, "", "trajectory"
        else:
            src = str(source)
            traj, name = open_trajectory(source), Path(src).stem
            if traj.settings.get("controller") is not None:
                raise ParameterError(f"{src}: a run with a controller, whose torques the file does not store; "
                                     "pass the Trajectory object instead")
        if not traj.kept:
            raise ParameterError(f"{src or 'the trajectory'}: only its first and last rows were kept (keep=False); "
                                 "simulate with keep=True")
        tau = np.array([float(traj.params.value(f"tau{i}") or 0.0) for i in range(1, traj.params.n + 1)])
        n = tau.size
        u = None
        if traj.controller is not None:
            u = traj.inputs() + tau
        elif np.any(tau != 0):
            u = np.tile(tau, (len(traj.t), 1))
        y = np.asarray(traj.y, dtype=float)
        extra = {"params": traj.params.to_dict(), "run": traj.message}
        return cls.from_arrays([{"t": traj.t, "q": y[:, :n], "dq": y[:, n:2 * n], "u": u, "name": name}],
                               source=src, format="trajectory", extra=extra, **checks)


def _thaw(value):
    if isinstance(value, Mapping):
        return {k: _thaw(v) for k, v in value.items()}
    if isinstance(value, tuple):
        return [_thaw(v) for v in value]
    return value


# -- file helpers -------------------------------------------------------------------------------------
def _paths(path, pattern: str = "*.csv") -> List[Path]:
    items = [path] if isinstance(path, (str, Path)) else list(path)
    if not items:
        raise ParameterError("no file given")
    out: List[Path] = []
    for item in items:
        p = Path(item)
        if p.is_dir():
            found = sorted(p.glob(pattern))
            if not found:
                raise ParameterError(f"{p}: a folder with no {pattern} in it")
            out.extend(found)
        elif not p.is_file():
            raise ParameterError(f"{p} does not exist")
        else:
            out.append(p)
    return out


def _read_csv_piece(path: Path, columns: Mapping[str, Any], delimiter: str) -> Dict[str, Any]:
    unknown = [k for k in columns if k not in _COLUMN_KEYS]
    if unknown:
        raise ParameterError(f"columns: unknown key {unknown[0]!r}; the keys: {', '.join(_COLUMN_KEYS)}",
                             parameter="columns")
    for need in ("t", "phi", "psi"):
        if columns.get(need) is None:
            raise ParameterError(f"columns must name the {need!r} column", parameter="columns")
    for a, b in (("dphi", "dpsi"), TORQUE_NAMES):
        if (columns.get(a) is None) != (columns.get(b) is None):
            raise ParameterError(f"columns: {a} and {b} come together (give both or neither; a torque may be "
                                 "a number such as 0.0 for an unactuated joint)", parameter="columns")
    _check_text_file(path)
    try:
        with open(path, newline="") as fh:
            header = [h.strip() for h in next(csv.reader(fh, delimiter=delimiter))]
    except StopIteration:
        raise ParameterError(f"{path} is empty") from None
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise ParameterError(f"{path} cannot be read as text: {exc}") from None
    wanted = {k: v for k, v in columns.items() if isinstance(v, str)}
    missing = [v for v in wanted.values() if v not in header]
    if missing:
        raise ParameterError(f"{path}: no column {missing[0]!r}; its columns: {', '.join(header)}",
                             parameter="columns")
    index = {k: header.index(v) for k, v in wanted.items()}
    use = sorted(set(index.values()))
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # a header and no rows: said below, in one line
        try:
            table = np.loadtxt(path, delimiter=delimiter, skiprows=1, usecols=use, ndmin=2)
        except ValueError:
            # say which line and column is not a number, or too short; empty fields are NaN (then counted and
            # dropped or refused by the checks)
            _scan_csv(path, delimiter, use, header)
            try:
                table = np.genfromtxt(path, delimiter=delimiter, skip_header=1, usecols=use, ndmin=2)
            except ValueError as exc:
                raise ParameterError(f"{path}: not a table of numbers ({_first_line(exc)})") from None
    if table.size == 0:
        raise ParameterError(f"{path}: a header line and no rows of data")
    col = {k: table[:, use.index(i)] for k, i in index.items()}
    n = len(table)

    def pair(a: str, b: str):
        if columns.get(a) is None:
            return None
        return np.column_stack([col[k] if k in col else np.full(n, float(columns[k])) for k in (a, b)])

    for k in TORQUE_NAMES + ("dphi", "dpsi"):
        v = columns.get(k)
        if v is not None and not isinstance(v, str) and not isinstance(v, (int, float)):
            raise ParameterError(f"columns: {k} must be a column name or a number", parameter="columns")
    for k in ("t", "phi", "psi", "dphi", "dpsi"):
        v = columns.get(k)
        if v is not None and not isinstance(v, str):
            raise ParameterError(f"columns: {k} must be a column name, got {v!r}", parameter="columns")
    return {"t": col["t"], "q": np.column_stack([col["phi"], col["psi"]]), "dq": pair("dphi", "dpsi"),
            "u": pair(*TORQUE_NAMES), "name": path.stem, "source": str(path)}


#: The longest first line (the header) a CSV file may have [bytes]; and how much of its start and end
#: is looked at for NUL bytes (a binary or sparse file) before any parsing.
HEADER_BYTES = 1 << 20
PROBE_BYTES = 1 << 16


def _first_line(exc) -> str:
    return " ".join(str(exc).split("\n")[0].split())


def _check_text_file(path: Path) -> None:
    """Refuse, in a line and at once, a file that is no text table: NUL bytes near its start or end (a
    binary file, or a sparse one of holes), or a first line longer than :data:`HEADER_BYTES`."""
    try:
        size = path.stat().st_size
        with open(path, "rb") as fh:
            head = fh.read(PROBE_BYTES)
            tail = b""
            if size > 2 * PROBE_BYTES:
                fh.seek(size - PROBE_BYTES)
                tail = fh.read(PROBE_BYTES)
            if b"\0" in head or b"\0" in tail:
                raise ParameterError(f"{path} holds NUL bytes ({size:,} bytes in all): not a text table (a binary "
                                     "or sparse file?)")
            fh.seek(0)
            first = fh.readline(HEADER_BYTES + 1)
    except OSError as exc:
        raise ParameterError(f"{path} cannot be read: {exc.strerror or exc}") from None
    if len(first) > HEADER_BYTES:
        raise ParameterError(f"{path}: its first line is longer than {HEADER_BYTES:,} bytes: not a CSV header "
                             "(a header line names the columns)")


def _scan_csv(path: Path, delimiter: str, use: Sequence[int], header: Sequence[str]) -> None:
    """The first line of ``path`` whose used fields are not numbers or too few, as one ParameterError
    naming the line and the column (empty fields pass: NaN)."""
    with open(path, newline="") as fh:
        reader = csv.reader(fh, delimiter=delimiter)
        try:
            next(reader)
            for line, row in enumerate(reader, start=2):
                if not row:
                    continue
                if len(row) <= max(use):
                    raise ParameterError(f"{path}: line {line} has {len(row)} field(s), the header {len(header)}: "
                                         "a row cut short or a wrong delimiter")
                for i in use:
                    text = row[i].strip()
                    if not text:
                        continue
                    try:
                        float(text)
                    except ValueError:
                        raise ParameterError(f"{path}: line {line}, column {header[i]!r}: {text[:40]!r} is not a "
                                             "number") from None
        except csv.Error as exc:
            raise ParameterError(f"{path}: not a CSV table ({exc})") from None


def _load_mat(path: Path) -> Dict[str, Any]:
    from scipy.io import loadmat

    if not path.is_file():
        raise ParameterError(f"{path} does not exist")
    try:
        return loadmat(str(path))
    except NotImplementedError:
        raise ParameterError(f"{path} is a MATLAB v7.3 (HDF5) file: save it with -v7, or read it with h5py "
                             "and use Measurements.from_arrays") from None
    except (ValueError, OSError, TypeError) as exc:
        raise ParameterError(f"{path} is not a MATLAB .mat file scipy can read ({exc})") from None


def _variable(mat: Mapping[str, Any], name: str, path: Path):
    if name not in mat:
        names = [k for k in mat if not k.startswith("__")]
        raise ParameterError(f"{path}: no variable {name!r}; it holds {', '.join(names)}")
    return mat[name]


def _cells(value) -> List[np.ndarray]:
    """The pieces of a cell array (MATLAB order), or ``[value]`` for a plain array."""
    a = np.asarray(value)
    if a.dtype == object:
        return [np.asarray(x) for x in a.ravel(order="F")]
    return [a]


# -- the published model of the Kaheman rig ------------------------------------------------------------
def _estimated(path, data_file: str, parameters_file: str, names: str) -> np.ndarray:
    """The authors' ``EstimatedParameters`` (``path``: their file, the data file beside it or their folder),
    refused in one line unless it holds the finite numbers ``names`` lists."""
    path = Path(path)
    if path.is_dir():
        path = path / parameters_file
    elif path.name == data_file:
        path = path.parent / parameters_file
    mat = _load_mat(path)
    values = np.asarray(_variable(mat, "EstimatedParameters", path), dtype=float).ravel()
    count = len(names.split())
    if values.size != count or not np.all(np.isfinite(values)):
        raise ParameterError(f"{path}: EstimatedParameters must hold {count} finite numbers [{names}], got {values.size}")
    return values


def kaheman_published_parameters(path):
    """The model Kaheman et al. (2023) identified for their free-swing pendulum, in skewpend's terms,
    from ``EstimatedParameters_DoublePendulum.mat`` (``path``: that file, the data file beside it or
    their folder, ``data/kaheman2023``).  Their ``[m1 m2 a1 a2 L1 I1 I2 k1 k2 g]`` become ``a = L1``,
    ``m1``, ``m2``, ``com1 = (0, a1, 0)``, ``com2 = (0, a2, 0)``, inertias ``I1``, ``I2`` about ``k``
    (and ``i``: a rod's moment about its own axis ``j`` is 0), ``c1 = k1``, ``c2 = k2``, ``g``,
    ``alpha = 0`` and ``b = 2 a2`` (rod 2's length does not enter their model; it only places the tip).
    The start ``params0`` of ``skewpend identify --format kaheman``."""
    from ..symbolic.model import Parameters

    values = _estimated(path, KAHEMAN_FILE, KAHEMAN_PARAMETERS_FILE, "m1 m2 a1 a2 L1 I1 I2 k1 k2 g")
    m1, m2, a1, a2, L1, I1, I2, k1, k2, g = (float(x) for x in values)
    return Parameters(a=L1, b=2 * a2, m1=m1, m2=m2, alpha=0, g=g, c1=k1, c2=k2, com1=(0, a1, 0), com2=(0, a2, 0),
                      inertia1=((I1, 0, 0), (0, 0, 0), (0, 0, I1)), inertia2=((I2, 0, 0), (0, 0, 0), (0, 0, I2)))


def kaheman_published_chain(path, g: float = 9.8083):
    """The model Kaheman et al. (2023) identified for their free-swing triple pendulum, as a chain of
    three links, from ``EstimatedParameters_TriplePendulum.mat`` (``path``: that file, the data file
    beside it or their folder, ``kaheman2023-triple``).  Their ``[m1 m2 m3 a1 a2 a3 L1 L2 I1 I2 I3 k1
    k2 k3 g]`` (``a_i`` joint ``i`` to arm ``i``'s centre of mass, ``L1``, ``L2`` joint to joint, ``I_i``
    about each centre of mass, ``k1`` on ``dtheta1``, ``k2`` on ``dtheta2 - dtheta1``, ``k3`` on
    ``dtheta3 - dtheta2``) become links on parallel axes ``k`` of lengths ``L1``, ``L2``, ``2 a3`` (the
    last only places the tip), ``com = (0, a_i, 0)``, inertia ``I_i`` about ``k`` and ``i`` (a rod's
    moment about its own axis ``j`` is 0) and joint damping ``k_i`` on the relative speeds, which are
    skewpend's coordinates.  ``g``: their scripts pass the stored 15th value only for vectors of
    length 10 or 14, so their fit and validation used 9.8083 (the default here); pass ``g=None`` for
    the stored value."""
    from ..symbolic.chain import Chain, Link

    values = _estimated(path, KAHEMAN_TRIPLE_FILE, KAHEMAN_TRIPLE_PARAMETERS_FILE,
                        "m1 m2 m3 a1 a2 a3 L1 L2 I1 I2 I3 k1 k2 k3 g")
    m, a, (L1, L2), inertia, k = values[0:3], values[3:6], values[6:8], values[8:11], values[11:14]
    lengths = (L1, L2, 2 * a[2])
    links = tuple(Link(length=float(lengths[i]), mass=float(m[i]), com=(0.0, float(a[i]), 0.0),
                       inertia=((float(inertia[i]), 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, float(inertia[i]))),
                       damping=float(k[i])) for i in range(3))
    return Chain(links=links, g=float(values[14]) if g is None else float(g))


def dfki_lab_parameters(path):
    """One of the DFKI lab's identified models of its rig (``model_*_parameters.yml``: ``m1, m2, l1,
    l2, r1, r2``, ``I1, I2`` about the joints, ``Ir``, ``gr``, ``b1, b2``, ``cf1, cf2``, ``g``; ``path``
    that file) in skewpend's terms: ``a = l1``, ``b = l2``, centres of mass ``(0, r, 0)``, inertias
    about them ``I - m r^2`` (about ``k`` and ``i``), ``c = b``, Coulomb friction ``cf`` at ``cfs = 100``
    (the lab's ``atan(100 q')``), the rotor ``Ir`` at ``gr = -gr_lab`` (the lab's cross term ``-gr Ir``
    is a rotor turning against the joint; see the guide), ``alpha = 0``.

    Only the base parameters enter the equations (``I1 + m2 l1^2``, ``m1 r1 + m2 l1``, ``I2``,
    ``m2 r2``, ...).  Where the lab's own split is not a physical body (model 3.0: ``I2 < m2 r2^2``, a
    negative inertia about the centre of mass) the masses are raised until it is (each body's inertia
    about its centre of mass then a fifth of its inertia about the joint), keeping every base
    parameter: the model moves exactly as the lab's."""
    return dfki_parameters(read_dfki_lab_values(path))


def read_dfki_lab_values(path) -> Dict[str, float]:
    """The numbers of one of the DFKI lab's model files (``model_*_parameters.yml``), by the lab's names
    (:data:`DFKI_KEYS`, and the torque limits ``tl1``, ``tl2`` when there)."""
    return _read_dfki_yml(Path(path))


def dfki_parameters(v):
    """The lab's model numbers ``v`` (a mapping by the lab's names, :data:`DFKI_KEYS`) in skewpend's terms:
    see :func:`dfki_lab_parameters`."""
    from ..symbolic.model import Parameters

    l1 = v["l1"]
    J1, h1, J2, h2 = v["I1"] + v["m2"] * l1**2, v["m1"] * v["r1"] + v["m2"] * l1, v["I2"], v["m2"] * v["r2"]
    m2 = v["m2"] if J2 > h2**2 / v["m2"] else 1.25 * h2**2 / J2
    I1j, m1r1 = J1 - m2 * l1**2, h1 - m2 * l1
    m1 = v["m1"] if I1j > m1r1**2 / v["m1"] else 1.25 * m1r1**2 / I1j
    r1, r2 = m1r1 / m1, h2 / m2
    I1c, I2c = I1j - m1 * r1**2, J2 - m2 * r2**2
    return Parameters(a=l1, b=v["l2"], m1=m1, m2=m2, alpha=0.0, g=v["g"], com1=(0, r1, 0), com2=(0, r2, 0),
                      inertia1=((I1c, 0, 0), (0, 0, 0), (0, 0, I1c)), inertia2=((I2c, 0, 0), (0, 0, 0), (0, 0, I2c)),
                      c1=v["b1"], c2=v["b2"], cf1=v["cf1"], cf2=v["cf2"], cfs=100.0, Ir=v["Ir"], gr=-v["gr"])


#: The keys of a DFKI model file that skewpend reads and writes (the lab's ``model_parameters``
#: also has the torque limits ``tl1``, ``tl2``: read past, not written -- skewpend's model has none).
DFKI_KEYS = ("I1", "I2", "Ir", "b1", "b2", "cf1", "cf2", "g", "gr", "l1", "l2", "m1", "m2", "r1", "r2")
_YAML_SPECIAL = {".inf": math.inf, "+.inf": math.inf, "-.inf": -math.inf, ".nan": math.nan}


def _read_dfki_yml(path: Path) -> Dict[str, float]:
    """The numbers of a DFKI model file: one ``key: value`` per line, as the lab's ``yaml.dump``
    writes them (comments and blank lines skipped; YAML's ``.inf``, ``.nan`` read)."""
    if path.suffix.lower() not in (".yml", ".yaml"):
        raise ParameterError(f"{path}: a DFKI model file is a .yml file (model_*_parameters.yml)")
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise ParameterError(f"{path} cannot be read as text: {exc}") from None
    values: Dict[str, float] = {}
    for line in text.splitlines():
        line = line.split(" #", 1)[0].strip()
        if not line or line.startswith("#") or line == "---":
            continue
        key, sep, value = (x.strip() for x in line.partition(":"))
        if not sep or not key:
            raise ParameterError(f"{path}: expected 'key: number' lines as the lab's model files have, got {line!r}")
        try:
            values[key] = _YAML_SPECIAL[value.lower()] if value.lower() in _YAML_SPECIAL else float(value)
        except ValueError:
            raise ParameterError(f"{path}: {key} is not a number: {value!r}") from None
    missing = [k for k in DFKI_KEYS if k not in values]
    if missing:
        raise ParameterError(f"{path}: missing {', '.join(missing)} (a DFKI model_*_parameters.yml has them all)")
    bad = [k for k in DFKI_KEYS if not math.isfinite(values[k])]
    if bad:
        raise ParameterError(f"{path}: {bad[0]} must be a finite number, got {values[bad[0]]}")
    return values


def dfki_lab_values(params) -> Dict[str, float]:
    """A planar model in the DFKI lab's terms, the inverse of :func:`dfki_lab_parameters`:
    ``l1 = a``, ``l2 = b``, ``r`` the centre of mass along the rod, ``I = I_zz + m r^2`` about the
    joint axis, ``b = c``, ``cf``, ``Ir``, ``gr = -gr`` (the lab's sign), ``g``.  What does not
    enter a planar model's equations (``h1z``, the other inertia entries) is not carried.  Refused
    (one :class:`~skewpend.errors.ParameterError` saying why) when the model is not one the lab's
    equations describe: a skew angle or tilted axes, a centre of mass off the rod's line, a
    friction sharpness other than the lab's ``cfs = 100``, constant torques, symbolic values."""
    p = params.require_numeric("the DFKI lab's model file")
    if p.axis2 is None and float(p.alpha) != 0.0:
        raise ParameterError(f"the DFKI lab's model is planar; this model has alpha = {math.degrees(float(p.alpha)):.6g} "
                             "deg (write a .toml run file instead)")
    for name in AXIS_NAMES:
        axis = getattr(p, name)
        if axis is not None:
            n = np.asarray(axis, dtype=float)
            if np.hypot(n[0], n[1]) > 1e-12 * abs(n[2]):
                raise ParameterError(f"the DFKI lab's model is planar: both hinge axes along k; {name} = "
                                     f"({', '.join(f'{float(x):.6g}' for x in axis)}) "
                                     "(write a .toml run file instead)")
    if p.tau1 or p.tau2:
        raise ParameterError("the DFKI lab's model file has no constant joint torques; this model has tau1 = "
                             f"{p.tau1:g}, tau2 = {p.tau2:g}")
    if p.has_friction and p.cfs != 100.0:
        raise ParameterError(f"the DFKI lab's Coulomb friction is cf atan(100 q'); this model has cfs = {p.cfs:g}")
    out: Dict[str, float] = {}
    for k, m, length, com, inertia in ((1, p.m1, p.a, p.com1, p.inertia1), (2, p.m2, p.b, p.com2, p.inertia2)):
        x, r = (0.0, length / 2) if com is None else (float(com[0]), float(com[1]))
        if abs(x) > 1e-12 * max(abs(r), length):
            raise ParameterError(f"the DFKI lab's model has each centre of mass on its rod's line; com{k} is "
                                 f"{x:.6g} m off it (identify with --free leaving out h{k}x, or write a .toml run "
                                 "file instead)")
        izz = m * length**2 / 12 if inertia is None else float(inertia[2][2])
        out[f"m{k}"], out[f"l{k}"], out[f"r{k}"], out[f"I{k}"] = float(m), float(length), r, izz + m * r**2
    out.update(b1=float(p.c1), b2=float(p.c2), cf1=float(p.cf1), cf2=float(p.cf2), g=float(p.g), Ir=float(p.Ir),
               gr=-float(p.gr))
    return {k: out[k] for k in DFKI_KEYS}


def _yaml_number(x: float) -> str:
    """``repr`` (exact on reading back), with a dot before an exponent: YAML 1.1 (PyYAML) reads
    ``1e-05`` as text, ``1.0e-05`` as a number."""
    text = repr(float(x))
    if "e" in text and "." not in text.split("e")[0]:
        mantissa, exponent = text.split("e")
        text = f"{mantissa}.0e{exponent}"
    return text


def write_dfki_lab_parameters(params, path, *, header: Sequence[str] = ()) -> Path:
    """Write ``params`` as a DFKI model file (``model_*_parameters.yml``): ``key: number`` lines in
    the lab's order (``yaml.dump``'s sorted keys), numbers that read back exactly, after ``header``
    lines as YAML comments (``# ...``).  The conversion and its refusals: :func:`dfki_lab_values`;
    :func:`dfki_lab_parameters` reads the file back.  Written atomically; returns the path."""
    from ..io import atomic_path

    values = dfki_lab_values(params)
    path = Path(path)
    if path.suffix.lower() not in (".yml", ".yaml"):
        raise ParameterError(f"{path}: a DFKI model file is written as .yml")
    lines = [f"# {h}" for line in header for h in str(line).splitlines()]
    lines += [f"{k}: {_yaml_number(v)}" for k, v in values.items()]
    with atomic_path(path) as tmp:
        Path(tmp).write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path
