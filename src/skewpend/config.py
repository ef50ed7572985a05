"""Run settings as a person writes them: a TOML run file, values typed on a command line, defaults.

A *run* resolves, key by key, the built-in defaults, then a run file (``--config``), then the
values given on the command line; every value remembers where it came from, so a message can
name what the user typed (``--a``, or ``run.toml: [parameters] a``).

**The rule for run files, written once** (:data:`READS`): one run file serves every command.
Every key a command reads takes effect.  A run's sections a command does not use (``[initial]``,
``[simulation]``: a flip map starts on its grid, the modes need no start) are left aside with one
note (:attr:`Run.notes`, which the command line prints); in a section it does use, a key it does not
read is refused in one line naming the key and the command, as unknown keys are.  The model's
sections (``[parameters]``, ``[chain]``, ``[[links]]``) are never left aside: a command that does not
take a chain refuses them, and ``[chain]`` without links is refused.  Nothing in a run file is
ever silently ignored.

The parameters of the model are built in one way, :func:`build_parameters`, from values as the
user spelled them (numbers, ``"30deg"``, ``"pi/2"``, ``"sym"``, vectors, matrices).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable, Dict, Iterable, Mapping, Optional, Sequence, Tuple

from .errors import ParameterError
from .parsing import MAX_ANGLE, UsageError, parse_inertia, parse_scalar, parse_vector, parse_whole
from .schema import (CHAIN_NAMES, link_field_of, CORE_NAMES, GEOMETRY_NAMES, LINK_FIELDS, MAX_LINKS, MOTOR_KEYS, NAMES,
                     OPTIONAL_DEFAULTS, SCALAR_NAMES, check_bound, field)

__all__ = [
    "DEFAULT_RUN", "reference_parameters", "reference_state", "COMMAND_DEFAULTS", "READS", "MODEL_KEYS", "INITIAL_KEYS", "Run", "build_parameters", "as_text",
    "parameters_toml", "toml_value", "Motor", "MOTOR_READERS",
]

#: The run ``skewpend simulate`` does with no options (the reference case of the README).
DEFAULT_RUN: Dict[str, Dict[str, Any]] = {
    "parameters": dict(zip(CORE_NAMES, (1.0, 0.8, 1.0, 0.7, 0.6, 9.81))),
    "initial": {"phi0": 1.2, "psi0": -0.8, "dphi0": 0.0, "dpsi0": 0.0},
    "simulation": {"t_end": 20.0, "method": "dop853"},
}

def reference_parameters():
    """The reference case (:data:`DEFAULT_RUN`'s ``[parameters]``: the README's and the report's
    built-in model) as :class:`~skewpend.Parameters`.

    >>> import skewpend
    >>> p = skewpend.reference_parameters()
    >>> p.a, p.b, p.m1, p.m2, p.alpha, p.g
    (1.0, 0.8, 1.0, 0.7, 0.6, 9.81)
    """
    from .symbolic.model import Parameters

    return Parameters(**DEFAULT_RUN["parameters"])


def reference_state() -> Tuple[float, float, float, float]:
    """The reference case's initial state ``(phi, psi, dphi, dpsi)`` (:data:`DEFAULT_RUN`'s ``[initial]``)."""
    initial = DEFAULT_RUN["initial"]
    return tuple(float(initial[k]) for k in ("phi0", "psi0", "dphi0", "dpsi0"))  # type: ignore[return-value]


#: The settings a command needs that its library function does not default itself (the run
#: of simulate, animate and report is DEFAULT_RUN's; the Lyapunov spectrum's length).
COMMAND_DEFAULTS: Dict[str, Dict[str, Any]] = {
    "simulate": {**DEFAULT_RUN["simulation"], "method": "auto"},  # simulate(): the fastest method that serves the run
    "animate": DEFAULT_RUN["simulation"], "report": DEFAULT_RUN["simulation"],
    "lyapunov": {"t_end": 1000.0},
}

#: The model's keys ([parameters]) and the initial state's ([initial]).
SCALAR_KEYS = SCALAR_NAMES
MODEL_KEYS = frozenset(NAMES)
INITIAL_ORDER = ("phi0", "psi0", "dphi0", "dpsi0")
INITIAL_KEYS = frozenset(INITIAL_ORDER)
#: A chain's model (``[chain]``: g, cfs; ``[[links]]``: one table a link) and its start (``[initial]``:
#: the lists ``q0``, ``dq0``); the commands whose ``READS`` list them take a chain.
CHAIN_KEYS = frozenset(CHAIN_NAMES)
LINK_KEYS = frozenset(key for key, _, _ in LINK_FIELDS)
CHAIN_INITIAL_KEYS_ORDER = ("q0", "dq0")
CHAIN_INITIAL_KEYS = frozenset(CHAIN_INITIAL_KEYS_ORDER)
#: A chain's start when the run file gives none: every link turned by this angle [rad], at rest.
CHAIN_Q0 = 0.5
_INTEGRATION = frozenset(("t_end", "method", "rtol", "atol", "dt", "max_steps"))
_DOP853 = frozenset(("t_end", "method", "rtol", "atol"))  # the DOP853-only analyses

#: What each command reads of a run file, by section.  The one rule: a key listed takes effect,
#: any other key of a run file is refused, naming the key and the command.
READS: Dict[str, Dict[str, frozenset]] = {
    "simulate": {"parameters": MODEL_KEYS, "initial": INITIAL_KEYS | CHAIN_INITIAL_KEYS,
                 "simulation": _INTEGRATION | {"dt_out", "out", "plot"}, "chain": CHAIN_KEYS, "links": LINK_KEYS},
    "animate": {"parameters": MODEL_KEYS, "initial": INITIAL_KEYS | CHAIN_INITIAL_KEYS, "simulation": _INTEGRATION,
                "chain": CHAIN_KEYS, "links": LINK_KEYS},
    "report": {"parameters": MODEL_KEYS, "initial": INITIAL_KEYS | CHAIN_INITIAL_KEYS, "simulation": _INTEGRATION,
               "chain": CHAIN_KEYS, "links": LINK_KEYS},
    "validate": {"parameters": MODEL_KEYS, "initial": INITIAL_KEYS | CHAIN_INITIAL_KEYS, "simulation": frozenset({"t_end"}),
                 "chain": CHAIN_KEYS, "links": LINK_KEYS},
    "lyapunov": {"parameters": MODEL_KEYS, "initial": INITIAL_KEYS | CHAIN_INITIAL_KEYS, "simulation": _DOP853 | {"max_steps"},
                 "chain": CHAIN_KEYS, "links": LINK_KEYS},
    "flipmap": {"parameters": MODEL_KEYS, "simulation": _DOP853, "chain": CHAIN_KEYS, "links": LINK_KEYS},
    "poincare": {"parameters": MODEL_KEYS, "simulation": frozenset(("method", "rtol", "atol"))},
    "chaos-diagram": {"parameters": MODEL_KEYS - {"alpha"}, "simulation": _DOP853},
    "export": {"parameters": MODEL_KEYS, "chain": CHAIN_KEYS, "links": LINK_KEYS},
    "modes": {"parameters": MODEL_KEYS, "chain": CHAIN_KEYS, "links": LINK_KEYS},
    "equilibria": {"parameters": MODEL_KEYS, "chain": CHAIN_KEYS, "links": LINK_KEYS},
    "orbit": {"parameters": MODEL_KEYS, "initial": INITIAL_KEYS | CHAIN_INITIAL_KEYS, "chain": CHAIN_KEYS, "links": LINK_KEYS},
    "nnm": {"parameters": MODEL_KEYS, "chain": CHAIN_KEYS, "links": LINK_KEYS},
    "control": {"parameters": MODEL_KEYS, "chain": CHAIN_KEYS, "links": LINK_KEYS},
    "identify": {"parameters": MODEL_KEYS, "chain": CHAIN_KEYS, "links": LINK_KEYS},  # params0, the fit's start
    "derive": {"parameters": MODEL_KEYS, "chain": CHAIN_KEYS, "links": LINK_KEYS},  # the values given; the others stay symbolic
    # the bodies and axes -> the generated physics; the scalars and the start -> the page's sliders
    # the start's rates: the explorer starts at rest, so they are read to be checked 0 (skewpend serve)
    "serve": {"parameters": MODEL_KEYS, "initial": INITIAL_KEYS | CHAIN_INITIAL_KEYS, "chain": CHAIN_KEYS,
              "links": LINK_KEYS},
}

#: The commands that read a run file's ``[motor]`` (a voltage-driven DC motor on a chain's joint, :class:`Motor`):
#: those that compute the chain's motion or its model, where the motor's back-EMF is its joint's damping and the
#: motor at 0 V is the model (the explorer's too: it has no voltage input), and ``control``, whose controllers
#: drive it: its joint actuated, its torque limit kt Vmax / R their ``umax`` (unless ``--actuated``/``--umax`` say
#: otherwise), the back-EMF in the joint's damping (``export``: its actuator, the voltage its input).  The others
#: refuse it.
MOTOR_READERS = ("simulate", "animate", "report", "validate", "lyapunov", "flipmap", "modes", "equilibria", "orbit",
                 "nnm", "identify", "derive", "serve", "control", "export")
#: The readers that say the motor's note themselves: what they take of it depends on their options
#: (``control``: :meth:`Motor.control_note`).
MOTOR_NOTED_BY_COMMAND = ("control",)
for _command in MOTOR_READERS:
    READS[_command] = {**READS[_command], "motor": frozenset(MOTOR_KEYS)}


@dataclass(frozen=True)
class Motor:
    """A voltage-driven DC motor on joint ``joint`` (1-based) of a chain: armature ``resistance`` R [ohm],
    ``torque_constant`` kt [N m/A], ``back_emf_constant`` km [V s/rad], ``voltage_limit`` Vmax [V] (a run file's
    ``[motor]``).  Its torque on the joint, ``kt (V - km q') / R``, is the viscous damping ``kt km / R``
    (:attr:`damping`, added to the joint's by :meth:`apply`) and the input ``kt V / R`` (:attr:`gain` N m per
    volt), at most :attr:`torque_limit` = ``kt Vmax / R`` in magnitude.  Bad values: one line naming the key."""

    joint: int
    resistance: float
    torque_constant: float
    back_emf_constant: float
    voltage_limit: float

    def __post_init__(self) -> None:
        joint = self.joint
        if isinstance(joint, bool) or not isinstance(joint, int) and not (isinstance(joint, float) and joint.is_integer()):
            raise ParameterError(f"[motor] joint must be a joint's number (a whole number from 1), got {joint!r}")
        if not joint >= 1:
            raise ParameterError(f"[motor] joint must be a joint's number (a whole number from 1), got {joint!r}")
        object.__setattr__(self, "joint", int(joint))
        for key in MOTOR_KEYS[1:]:
            value = getattr(self, key)
            ok = isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value) and value > 0
            if not ok:
                raise ParameterError(f"[motor] {key} must be a finite number > 0, got {value!r}")
            object.__setattr__(self, key, float(value))

    @classmethod
    def from_mapping(cls, data: Mapping[str, Any]) -> "Motor":
        """A motor from a run file's ``[motor]`` table (every key required; an unknown key refused)."""
        unknown = sorted(k for k in data if k not in MOTOR_KEYS)
        if unknown:
            raise ParameterError(f"[motor]: unknown key {unknown[0]!r}; a motor takes {', '.join(MOTOR_KEYS)}")
        missing = [k for k in MOTOR_KEYS if data.get(k) is None]
        if missing:
            raise ParameterError(f"[motor] needs {', '.join(missing)} (a motor takes {', '.join(MOTOR_KEYS)})")
        return cls(**{k: data[k] for k in MOTOR_KEYS})

    @property
    def damping(self) -> float:
        """The back-EMF's viscous damping ``kt km / R`` [N m s]."""
        return self.torque_constant * self.back_emf_constant / self.resistance

    @property
    def gain(self) -> float:
        """The input's torque per volt ``kt / R`` [N m/V]."""
        return self.torque_constant / self.resistance

    @property
    def torque_limit(self) -> float:
        """The largest input torque ``kt Vmax / R`` [N m] (the controllers' ``umax``)."""
        return self.gain * self.voltage_limit

    def torque(self, voltage, speed):
        """The motor's torque on its joint ``kt (V - km q') / R`` [N m] at ``voltage`` [V] and the joint's ``speed``."""
        return self.gain * (voltage - self.back_emf_constant * speed)

    def voltage(self, torque):
        """The voltage [V] of an input torque ``u`` [N m] (a controller's, the back-EMF in the joint's damping):
        ``u R / kt``."""
        return torque / self.gain

    def apply(self, chain):
        """``chain`` with the back-EMF's damping added to joint :attr:`joint`'s (a joint it lacks: one line)."""
        if self.joint > chain.n:
            raise ParameterError(f"[motor] joint = {self.joint}, but the chain has {chain.n} joint"
                                 f"{'s' if chain.n != 1 else ''}")
        link = chain.links[self.joint - 1]
        return chain.replace_link(self.joint, damping=link.damping + self.damping)

    def describe(self) -> str:
        """The conversion in one line."""
        return (f"[motor] on joint {self.joint}: back-EMF kt km/R = {self.damping:.6g} N m s added to joint "
                f"{self.joint}'s damping; input kt V/R = {self.gain:.6g} N m per volt, |V| <= {self.voltage_limit:g} V "
                f"is |u| <= {self.torque_limit:.6g} N m")

    def control_actuators(self, actuated, umax):
        """What ``skewpend control`` drives: ``(actuated, umax, said)`` -- the given ``--actuated`` and ``--umax``
        where given (they win), else the motor's joint and, where that joint alone is actuated, its
        :attr:`torque_limit`; ``said`` the note's words on each."""
        said = []
        if actuated is None:
            actuated = (self.joint,)
            said.append(f"--actuated {self.joint} (its joint)")
        else:
            said.append(f"--actuated {actuated if isinstance(actuated, str) else ','.join(map(str, actuated))} as given")
        if umax is not None:
            shown = f"{umax:g}" if isinstance(umax, (int, float)) else ",".join(f"{u:g}" for u in umax)
            said.append(f"--umax {shown} as given")
        elif not isinstance(actuated, str) and tuple(actuated) == (self.joint,):
            umax = self.torque_limit
            said.append(f"--umax {self.torque_limit:.6g} (kt Vmax/R)")
        else:
            said.append("no --umax from it (it drives one joint of those actuated)")
        return actuated, umax, said

    def control_note(self, said) -> str:
        """``skewpend control``'s note: the conversion and what the controllers take of it (:meth:`control_actuators`)."""
        return f"{self.describe()} (skewpend control: {', '.join(said)}; the back-EMF in the joint's damping)"


#: The sections a command may leave aside (with one note) when it does not use them: the run's start and
#: its integration.  The model's sections are never left aside.
IGNORABLE_SECTIONS = ("initial", "simulation")

#: Why a command does not read a key that some other command does (the refusal says it).
_WHY_NOT = {
    ("chaos-diagram", "alpha"): "the chaos diagram varies alpha itself (give the angles with --alphas START:STOP:COUNT)",
    ("animate", "dt_out"): "the frames are the rows (dt_out = speed/fps), written to --out",
    ("animate", "out"): "the video is written to --out FILE.mp4|.gif",
    ("animate", "plot"): "an animation draws no plot",
    ("report", "out"): "the report is written to --out FILE.html",
    ("report", "dt_out"): "the report draws the integrator's own steps",
    ("poincare", "t_end"): "each orbit runs until its crossings are recorded, or --t-max",
}


def _motor_refusal(config, command: str) -> str:
    """The one line refusing a run file's ``[motor]`` in a command that does not read it."""
    return (f"{config}: [motor] (a voltage-driven DC motor) is not read by skewpend {command}: it drives a joint of a "
            f"chain (read by skewpend {', '.join(MOTOR_READERS)})")


def as_text(value: Any, where: str = "value") -> Optional[str]:
    """A run file's value in the command line's spelling (vectors and matrices flattened to
    ``x,y,z``); numbers, strings and None pass through.  Booleans and tables are refused."""
    if value is None or isinstance(value, str):
        return value
    if isinstance(value, bool):
        raise UsageError(f"{where}: expected a number, got {str(value).lower()}")
    if isinstance(value, (list, tuple)):
        flat = []
        for v in value:
            flat.extend(v if isinstance(v, (list, tuple)) else [v])
        if any(isinstance(x, (bool, list, tuple, dict)) for x in flat):
            raise UsageError(f"{where}: expected numbers or symbol names, got {value!r}")
        return ",".join(repr(float(x)) if isinstance(x, (int, float)) else str(x) for x in flat)
    if isinstance(value, dict):
        raise UsageError(f"{where}: expected a number, got a table")
    if isinstance(value, (int, float)):
        return value  # parsed (and checked) by parse_scalar
    return repr(value)


def build_parameters(values: Mapping[str, Any], where: Optional[Mapping[str, str]] = None):
    """:class:`~skewpend.Parameters` from values as spelled (the one way of building them from
    user input).  A missing scalar stays symbolic, except the damping and torques ``c1, c2, tau1,
    tau2`` and the optional terms ``cf1, cf2, Ir`` (0 unless given), ``cfs`` (100) and ``gr`` (1):
    they take :class:`~skewpend.Parameters`' defaults (``"sym"`` makes them symbolic); ``where`` names each key as
    the user knows it (default ``--key``)."""
    from .symbolic.model import Parameters

    where = dict(where or {})

    def w(k):
        return where.get(k, "--" + k)

    def text(k):
        return as_text(values.get(k), w(k))

    scalars = {}
    for k in SCALAR_NAMES:  # a default of the schema (0: off; cfs 100 [s/rad], gr 1) or symbolic
        given = OPTIONAL_DEFAULTS.get(k) if values.get(k) is None else text(k)
        scalars[k] = parse_scalar(given, w(k), angle=field(k).bound == "angle")
    parse = {"vector": parse_vector, "inertia": parse_inertia}
    geometry = {k: parse[field(k).kind](text(k), w(k)) for k in GEOMETRY_NAMES}
    return Parameters(**scalars, **geometry)


#: The largest run file read [bytes] (a run file is a few hundred bytes; /dev/zero is endless).
MAX_RUN_FILE = 1 << 20


def _check_run_file(path) -> None:
    """A run file must be a regular file of at most :data:`MAX_RUN_FILE` bytes (a device, a FIFO
    or /dev/stdin would be read for ever); a missing one is reported by the reader."""
    import os
    import stat

    try:
        info = os.stat(path)
    except OSError:
        return  # read_config says what is wrong (missing, unreadable)
    if stat.S_ISDIR(info.st_mode):
        return
    if not stat.S_ISREG(info.st_mode):
        raise UsageError(f"config file {path} is not a regular file (a device or a pipe); give a TOML file")
    if info.st_size > MAX_RUN_FILE:
        raise UsageError(f"config file {path} is {info.st_size} bytes; a run file is at most {MAX_RUN_FILE} bytes of TOML")


class Run:
    """The resolved settings of one command: defaults, then the run file, then the command line.

    ``command`` names the command (a key of :data:`READS`); ``config`` is the run file or None;
    ``given`` maps a section to the values typed on the command line (None: not given);
    ``defaults`` adds :data:`DEFAULT_RUN` (False: a missing parameter stays symbolic).
    """

    def __init__(self, command: str, config: Optional[str] = None, given: Optional[Mapping[str, Mapping[str, Any]]] = None,
                 *, defaults: bool = True, flags: Optional[Mapping[str, str]] = None,
                 read: Optional[Callable[[str], Tuple[Dict[str, Any], Sequence[str]]]] = None) -> None:
        """``read``: how ``config`` is read, ``path -> (sections, notes)`` (default: a TOML run file; the command
        line reads a MuJoCo or URDF model file into a chain's sections this way)."""
        from .io import read_config

        self.command = command
        sections = (*DEFAULT_RUN, "chain", "motor")
        self.values: Dict[str, Dict[str, Any]] = {k: {} for k in sections}
        self.where: Dict[str, Dict[str, str]] = {k: {} for k in sections}
        self.given: Dict[str, set] = {k: set() for k in sections}
        self._flags = dict(flags or {})
        if defaults:  # the reference case, and the settings the command's library function needs
            for section, values in {**DEFAULT_RUN, "simulation": COMMAND_DEFAULTS.get(command, {})}.items():
                for k, v in values.items():
                    self._set(section, k, v, f"default {k}", given=False)
        self.links: Optional[list] = None  # a chain's [[links]] tables, as written
        #: What the command line says before the work (one line each): the sections of the run file left aside.
        self.notes: list = []
        self.config = config
        if config is not None:
            _check_run_file(config)
            reads = READS.get(command, {})
            if read is None:
                sections = read_config(config)
            else:
                sections, said = read(config)
                self.notes.extend(f"{config}: {note}" for note in said)
            if ("links" in sections or sections.get("chain")) and "links" not in reads:
                takers = ", ".join(c for c, r in READS.items() if "links" in r)
                what = "[[links]]" if "links" in sections else "[chain]"
                raise UsageError(f"{config}: {what} (a chain of links) is not read by skewpend {command}: it "
                                 f"computes the double pendulum's [parameters] (chains: skewpend {takers})")
            if sections.get("motor") and "motor" not in reads:
                raise UsageError(_motor_refusal(config, command))
            unused = [s for s in IGNORABLE_SECTIONS if sections.get(s) and s not in reads]
            if unused:
                self.notes.append(f"{config}: {' and '.join(f'[{s}]' for s in unused)} {'is' if len(unused) == 1 else 'are'} "
                                  f"not used by skewpend {command}; ignored")
            aside = []  # keys of another command in a section this one uses (read_config refused unknown keys)
            for section, values in sections.items():
                if section == "links":
                    self.links = values
                    continue
                if section in unused:
                    continue
                for k, v in values.items():
                    if k not in reads.get(section, ()):
                        if section not in IGNORABLE_SECTIONS:  # the model's sections are never left aside
                            why = _WHY_NOT.get((command, k), "it is a setting of another command")
                            raise UsageError(f"{config}: [{section}] {k} is not read by skewpend {command}: {why}; "
                                             f"remove it from the run file, or give this command its own")
                        aside.append((section, k))
                        continue
                    self._set(section, k, v, f"{config}: [{section}] {k}")
            if aside:  # one file serves every command: another command's settings are left aside, said once
                whys = [_WHY_NOT[(command, k)] for _, k in aside if (command, k) in _WHY_NOT]
                self.notes.append(f"{config}: {', '.join(f'[{s}] {k}' for s, k in aside)} "
                                  f"{'is a setting' if len(aside) == 1 else 'are settings'} of other commands, not used by "
                                  f"skewpend {command}; ignored" + (f" ({'; '.join(whys)})" if whys else ""))
        given = {section: dict(values) for section, values in (given or {}).items()}
        per_link = {k: given["parameters"].pop(k) for k in list(given.get("parameters", {}))
                    if (k == "links" or k.startswith("link_")) and given["parameters"][k] is not None}
        self._cli_link_keys: set = set()  # the links' fields given on the command line (--link-mass, ...)
        self._links_count_given = False  # --links N typed
        if per_link:
            self._links_from_options(per_link)
        for section, values in given.items():
            for k, v in values.items():
                if v is not None:
                    self._set(section, k, v, self.flag(k))
        if self.links is None and self.given["chain"]:  # a chain's g without its links: never the double pendulum's g
            key = sorted(self.given["chain"])[0]
            raise UsageError(f"{self.option('chain', key)} is a chain's value, but the run has no links ([[links]] tables "
                             f"or --links N): give the chain's links, or the double pendulum's {key} as [parameters] {key}")
        #: the run file's motor (:class:`Motor`), or None; the chain carries its damping (:meth:`chain`)
        self.motor: Optional[Motor] = None
        if self.values["motor"]:
            self.motor = self._motor()
        P = self.values["parameters"]
        if "axis2" in P and "alpha" in P and "alpha" not in self.given["parameters"]:
            del P["alpha"]  # the built-in alpha gives way to a user's axis2

    def _motor(self) -> "Motor":
        """The run file's ``[motor]``, checked against its links, its conversion said in a note."""
        where = f"{self.config}: " if self.config else ""
        if self.links is None:
            raise UsageError(f"{where}[motor] drives a joint of a chain of links: give the chain's [[links]] tables "
                             "(the double pendulum's joint damping is [parameters] c1, c2)")
        try:
            motor = Motor.from_mapping(self.values["motor"])
        except ParameterError as exc:
            raise UsageError(f"{where}{exc}") from None
        if motor.joint > len(self.links):
            raise UsageError(f"{where}[motor] joint = {motor.joint}, but the chain has {len(self.links)} joint"
                             f"{'s' if len(self.links) != 1 else ''}")
        if self.command == "export":
            self.notes.append(f"{where}{motor.describe()} (skewpend export writes it as joint {motor.joint}'s actuator "
                              f"whose control is the voltage (MJCF), its effort limit (URDF))")
        elif self.command not in MOTOR_NOTED_BY_COMMAND:
            self.notes.append(f"{where}{motor.describe()} (skewpend {self.command} applies 0 V: the limit is a "
                              f"controller's, e.g. skewpend.analysis.mpc.MPC(umax={motor.torque_limit:.6g}))")
        return motor

    def _links_from_options(self, per_link: Dict[str, Any]) -> None:
        """A chain from ``--links N`` and ``--link-FIELD`` values (one for every link, or one a link), over a run
        file's [[links]] when there is one."""
        first = self.flag(next(iter(per_link)))
        if "links" not in READS.get(self.command, {}):
            takers = ", ".join(c for c, r in READS.items() if "links" in r)
            raise UsageError(f"{first}: a chain of links is not taken by skewpend {self.command}: it computes the double "
                             f"pendulum (chains: skewpend {takers})")
        count = per_link.pop("links", None)
        self._links_count_given = count is not None
        lists = {k[len("link_"):]: v for k, v in per_link.items()}
        many = sorted({len(v) for v in lists.values() if len(v) > 1})
        n = count or (len(self.links) if self.links else None) or (many[-1] if many else None)
        if n is None:
            raise UsageError(f"{first}: how many links? give --links N (or one value a link)")
        for key, values in lists.items():
            if len(values) not in (1, n):
                raise UsageError(f"{self.flag('link_' + key)}: expected 1 or {n} values (one for every link, or one a link "
                                 f"of the {n}), got {len(values)}")
        if self.links is not None and len(self.links) != n:
            raise UsageError(f"--links {n}: the run file {self.config} has {len(self.links)} [[links]]; give as many, or "
                             "leave --links out")
        tables = [dict(t) for t in self.links] if self.links else [{} for _ in range(n)]
        for key, values in lists.items():
            for i, table in enumerate(tables):
                table[key] = values[0] if len(values) == 1 else values[i]
        self.links = tables
        self._cli_link_keys = set(lists)

    def flag(self, key: str) -> str:
        """The command-line option of ``key``."""
        return self._flags.get(key, "--" + key.replace("_", "-"))

    def _set(self, section, key, value, where, given=True):
        self.values[section][key] = value
        self.where[section][key] = where
        if given:
            self.given[section].add(key)

    # -- reading values -------------------------------------------------------------------------
    def option(self, section: str, key: str) -> str:
        """Where the value of ``key`` came from, as the user knows it."""
        return self.where[section].get(key, self.flag(key))

    def locations(self) -> Dict[str, str]:
        """Every key -> where its value came from (for messages that name a parameter)."""
        return {k: w for where in self.where.values() for k, w in where.items()}

    def is_given(self, section: str, key: str) -> bool:
        return key in self.given[section]

    def raw(self, section: str, key: str, default: Any = None) -> Any:
        return self.values[section].get(key, default)

    def text(self, section: str, key: str) -> Optional[str]:
        return as_text(self.values[section].get(key), self.option(section, key))

    def scalar(self, section: str, key: str, *, angle: bool = False) -> Optional[float]:
        return parse_scalar(self.text(section, key), self.option(section, key), angle=angle)

    def number(self, key: str, default: Optional[float] = None, *, low: float = 0.0, inclusive: bool = False,
               section: str = "simulation") -> Optional[float]:
        """A setting that is a number above ``low`` (at least ``low`` with ``inclusive``);
        ``default`` when not set; 'sym' is refused (a setting is never symbolic)."""
        if self.values[section].get(key) is None:
            return default
        where = self.option(section, key)
        value = parse_scalar(self.text(section, key), where)
        if value is None or not (value >= low if inclusive else value > low):
            bound = ("a non-negative" if inclusive else "a positive") if low == 0 else f"a number {'>=' if inclusive else '>'} {low:g}"
            raise UsageError(f"{where}: expected {bound} number, got {self.values[section][key]!r}")
        return value

    def whole(self, key: str, default: int, lo: int, hi: int, section: str = "simulation") -> int:
        if self.values[section].get(key) is None:
            return default
        value = self.values[section][key]
        return parse_whole(value, self.option(section, key), lo, hi)

    def path(self, key: str, section: str = "simulation") -> Optional[str]:
        value = self.values[section].get(key)
        if value is not None and not isinstance(value, str):
            raise UsageError(f"{self.option(section, key)}: expected a file name, got {value!r}")
        return value

    def settings(self, keys: Iterable[str], section: str = "simulation") -> Dict[str, float]:
        """The positive numeric settings among ``keys`` that are set (defaults included)."""
        return {k: self.number(k, section=section) for k in keys if self.values[section].get(k) is not None}

    # -- the model and the start ------------------------------------------------------------------
    def parameters(self):
        """The model of the run: the chain of its links where it gives them (``[[links]]``, ``--links``:
        :meth:`chain`), else the double pendulum's :class:`~skewpend.Parameters` (:func:`build_parameters`)."""
        if self.links is not None:
            return self.chain()
        return build_parameters(self.values["parameters"], self.where["parameters"])

    def start_options(self) -> Tuple[str, ...]:
        """The options that give the run's start, as the user types them: a chain's lists ``--q0 --dq0``, or
        one a coordinate and rate (``--phi0 --psi0 --dphi0 --dpsi0``)."""
        keys = CHAIN_INITIAL_KEYS_ORDER if self.links is not None else tuple(INITIAL_ORDER)
        return tuple(self.flag(k) for k in keys)

    def links_source(self) -> str:
        """Where the chain's links came from, as the user knows it: ``--links`` or the run file's ``[[links]]``."""
        if self.config is not None and self.links is not None and not self._cli_link_keys and not self._links_count_given:
            return f"{self.config}: [[links]]"
        return self.flag("links")

    def chain(self):
        """The :class:`~skewpend.symbolic.chain.Chain` of the run file's ``[chain]`` and ``[[links]]``; the
        double pendulum's parameters given beside it (in the file or as options) are refused."""
        from .symbolic.chain import Chain

        # the chain's own g, cfs typed on the command line (--g) are its; the double pendulum's others are not
        typed = {k for k in self.given.get("parameters", ()) if self.option("parameters", k).startswith("--")}
        given = sorted(k for k in self.given.get("parameters", ()) if k not in CHAIN_NAMES or k not in typed)
        if given:
            alias = link_field_of(given[0])
            if alias is None:
                instead = "give each link's values in its [[links]] table or as --link-FIELD"
            else:
                key, i = alias
                which = f"link {i}'s {key}" if i else f"each link's {key}"
                what = " (the hinge's axis, e.g. 0.5,0,0.87 for a tilt of 30 deg from k towards i)" if key == "axis" else ""
                instead = (f"give {which}{what} as --link-{key} (one value for every link, or one a link) or as "
                           f"{key} in its [[links]] table")
            raise UsageError(f"{self.option('parameters', given[0])}: a chain of links ([[links]] or --links) does not take "
                             f"the double pendulum's parameters: {instead} (the chain's g is --g or [chain] g)")
        values = {k: parse_scalar(self.text("chain", k), self.option("chain", k)) for k in CHAIN_NAMES
                  if self.values.get("chain", {}).get(k) is not None}
        values.update({k: parse_scalar(self.text("parameters", k), self.option("parameters", k)) for k in CHAIN_NAMES
                       if k in typed})
        for k, v in values.items():  # named as the user gave them (--g, or the run file's [chain] g)
            where = self.option("parameters", k) if k in typed else self.option("chain", k)
            if v is None:
                raise UsageError(f"{where}: a chain's values must be numeric, not 'sym' (a chain is a model to compute with)")
            problem = check_bound(k, v)
            if problem:
                raise UsageError(f"{where}: {problem}")
        if len(self.links or []) > MAX_LINKS:
            raise UsageError(f"{self.config}: [[links]]: a chain may have at most {MAX_LINKS} links, got {len(self.links)}")
        links = []
        for i, table in enumerate(self.links or [], start=1):
            link = {}
            for key, value in table.items():
                where = (f"{self.flag('link_' + key)} (link {i})" if key in self._cli_link_keys
                         else f"{self.config}: [[links]] {i} {key}")
                if isinstance(value, str):
                    value = parse_scalar(value, where, angle=False)
                link[key] = value
            links.append(link)
        try:
            chain = Chain.from_mapping({"links": links, **values})
            return chain if self.motor is None else self.motor.apply(chain)
        except ParameterError as exc:
            where = ", ".join([*([self.config] if self.config else []), *sorted(self.flag("link_" + k) for k in self._cli_link_keys)])
            raise UsageError(f"{where or self.flag('links')}: {exc}") from None

    def initial_state(self):
        """``[phi0, psi0, dphi0, dpsi0]``: numeric, the angles at most :data:`MAX_ANGLE` rad; for a chain
        ``q0 + dq0`` (``[initial]``'s lists; default every link at :data:`CHAIN_Q0` rad, at rest)."""
        if self.links is not None:
            return self._chain_state()
        for k in CHAIN_INITIAL_KEYS:
            if self.is_given("initial", k):
                raise UsageError(f"{self.option('initial', k)}: a chain's start (one value a link); the double pendulum's "
                                 "is phi0, psi0, dphi0, dpsi0")
        y0 = []
        for k in INITIAL_ORDER:
            value = self.scalar("initial", k, angle=k in ("phi0", "psi0"))
            if value is None:
                raise UsageError(f"{self.option('initial', k)}: the initial state must be numeric, not 'sym'")
            if k in ("phi0", "psi0") and abs(value) > MAX_ANGLE:
                raise UsageError(f"{self.option('initial', k)}: expected an angle of at most {MAX_ANGLE:g} rad in magnitude, got {value:g}")
            y0.append(value)
        return y0

    def _chain_state(self):
        n = len(self.links or [])
        out = []
        for key, default in (("q0", CHAIN_Q0), ("dq0", 0.0)):
            value = self.values["initial"].get(key)
            where = self.option("initial", key)
            if value is None:
                out += [default] * n
                continue
            items = list(value) if isinstance(value, (list, tuple)) else [value]
            if len(items) != n:
                raise UsageError(f"{where}: expected {n} values (one a link), got {len(items)}")
            for x in items:
                v = parse_scalar(as_text(x, where), where, angle=key == "q0")
                if v is None:
                    raise UsageError(f"{where}: the initial state must be numeric, not 'sym'")
                if key == "q0" and abs(v) > MAX_ANGLE:
                    raise UsageError(f"{where}: expected angles of at most {MAX_ANGLE:g} rad in magnitude, got {v:g}")
                out.append(v)
        for k in ("phi0", "psi0", "dphi0", "dpsi0"):
            if self.is_given("initial", k):
                raise UsageError(f"{self.option('initial', k)}: a chain's start is --q0 and --dq0 or [initial] q0 and dq0 (one value a link)")
        return out

    def integration(self, methods: Optional[Iterable[str]] = None) -> Dict[str, Any]:
        """The integrator settings (method, rtol, atol, dt, max_steps) that are set, checked
        against each other: tolerances go with the adaptive methods (dop853, taylor), a step with
        rk4 and gauss; a method outside ``methods`` (default: every method of ``simulate``) is
        refused."""
        from .numeric.simulation import ADAPTIVE, METHODS

        methods = tuple(METHODS if methods is None else methods)
        method = self.values["simulation"].get("method", "dop853")
        if not isinstance(method, str) or method not in methods:
            raise UsageError(f"{self.option('simulation', 'method')}: expected {' or '.join(methods)}, got {method!r}")
        adaptive = ADAPTIVE + ("auto",)  # simulate's default picks an adaptive method
        for key in ("rtol", "atol"):
            if method not in adaptive and self.is_given("simulation", key):
                raise UsageError(f"{self.option('simulation', key)} is a tolerance of {' and '.join(ADAPTIVE)}; {method} "
                                 "takes fixed steps (set --dt)")
        if method == "auto" and self.is_given("simulation", "dt"):
            raise UsageError(f"{self.option('simulation', 'dt')} is the step of rk4 and gauss; give --method rk4 or gauss with it "
                             "(the default method, auto, chooses its own steps: set --rtol/--atol)")
        if method in ADAPTIVE and self.is_given("simulation", "dt"):
            raise UsageError(f"{self.option('simulation', 'dt')} is the step of rk4 and gauss; {method} chooses its own steps (set --rtol/--atol)")
        out: Dict[str, Any] = {"method": method, **self.settings(("rtol", "atol", "dt"))}
        if self.values["simulation"].get("max_steps") is not None:
            from .checks import MAX_STEPS_LIMIT

            out["max_steps"] = self.whole("max_steps", 0, 1, MAX_STEPS_LIMIT)
        return out


def whole_multiple(value: float, unit: float) -> bool:
    """Whether ``value`` is a whole number of ``unit`` (to rounding)."""
    k = round(value / unit)
    return math.isclose(k * unit, value, rel_tol=1e-9, abs_tol=1e-12 * unit)


# -- writing a model back -----------------------------------------------------------------------
def toml_value(value: Any) -> str:
    """A parameter's value as TOML: numbers by ``repr`` (exact round trip), vectors and 3x3
    matrices as arrays, a symbol name as a string."""
    import json

    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(toml_value(v) for v in value) + "]"
    if isinstance(value, str):
        return json.dumps(value)
    return repr(float(value))


def chain_toml(chain) -> list:
    """The ``[chain]`` and ``[[links]]`` lines of a run file for a chain of links (the inverse of the
    run file's chain: ``Chain.from_mapping``), every value written with ``repr`` (it reads back exactly)."""
    data = chain.to_dict()
    out = ["[chain]"] + [f"{k} = {toml_value(v)}" for k, v in data.items() if k != "links"]
    for link in data["links"]:
        out += ["", "[[links]]"] + [f"{k} = {toml_value(v)}" for k, v in link.items()]
    return out


def parameters_toml(params) -> list:
    """The ``[parameters]`` lines of a run file for ``params`` (``key = value``, in the schema's
    order), the inverse of :func:`build_parameters`: the keys that are set; ``alpha`` only where it
    enters (no ``axis2``); the optional terms and the torques only where they differ from their
    default (off), so a run file does not spell out what is off, and reads back the same."""
    out = []
    for key in NAMES:
        value = getattr(params, key)
        if value is None or (key == "alpha" and not params.uses_alpha):
            continue
        if key in OPTIONAL_DEFAULTS and value == OPTIONAL_DEFAULTS[key]:
            continue
        out.append(f"{key} = {toml_value(value)}")
    return out
