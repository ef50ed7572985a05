"""One reader for every result skewpend writes: :func:`open_result`.

A result file says what it holds in its attribute ``kind`` (:attr:`ResultProtocol.result_kind`,
written by the result protocol); :func:`open_result` recognises the container by its content
(NetCDF/HDF5 signature, a Zarr group, skewpend's trajectory CSV header), reads ``kind`` and
returns the same result class with its data, ``params``, ``settings``, ``stats``, ``status``
and ``message``:

* a trajectory (``.nc`` or ``.csv``), a flip map, a Lyapunov map, a region of attraction and a
  chaos diagram (``.nc`` files or complete ``.zarr`` stores) go to their ``open_*`` readers;
* a Lyapunov spectrum, normal modes, a modes sweep, equilibria, a periodic orbit, a nonlinear
  normal mode (in energy or along alpha) and a Poincare section from ``.nc`` are rebuilt here.

Where a file holds only part of an object (the linearisation of an equilibrium, the monodromy
matrices of a family of orbits, the full states of a Poincare section's crossings), the missing
part is recomputed from the parameters and the stored data, and what the file stores is checked
against it to :data:`AGREEMENT` (relative to each quantity's scale): a file written by another
model -- edited parameters, another version of the equations -- is one
:class:`~skewpend.errors.ParameterError`, never a silently inconsistent object.  Stored arrays
are returned exactly as stored.
"""

from __future__ import annotations

import dataclasses
import json
import math
import re
from pathlib import Path
from typing import Any, Callable, Dict, List, Tuple

import numpy as np

from ..errors import ParameterError, SkewpendError
from ..status import Status
from ..symbolic.model import Parameters

__all__ = ["open_result", "result_kinds", "AGREEMENT"]

#: Relative agreement required between what a file stores and what its parameters give when the
#: missing parts are recomputed (the same model agrees to rounding, ~1e-12; another model by far
#: more than this).
AGREEMENT = 1e-6

#: The settings every :func:`skewpend.simulate` run records (None when unset: then not in its file).
SIMULATE_SETTINGS = ("t_end", "dt_out", "max_steps")

_HDF5 = b"\x89HDF\r\n\x1a\n"
_NETCDF3 = (b"CDF\x01", b"CDF\x02", b"CDF\x05")


# -- recognising the container -----------------------------------------------------------------------
def _container(path: Path) -> str:
    """``"netcdf"``, ``"zarr"`` or ``"csv"`` by content (the name's suffix must agree)."""
    if not path.exists():
        raise ParameterError(f"{path} does not exist")
    suffix = path.suffix.lower()
    if path.is_dir():
        if (path / "zarr.json").is_file() or (path / ".zgroup").is_file():
            if suffix != ".zarr":
                raise ParameterError(f"{path} is a Zarr store but its name does not end in .zarr; rename it")
            return "zarr"
        raise ParameterError(f"{path} is a directory, not a Zarr store made by skewpend (no group metadata in it)")
    if not path.is_file():
        raise ParameterError(f"{path} is not a regular file")
    try:
        with open(path, "rb") as fh:
            head = fh.read(512)
    except OSError as exc:
        raise ParameterError(f"{path} cannot be read: {exc.strerror or exc}") from None
    if not head:
        raise ParameterError(f"{path} is empty, not a result file")
    if head.startswith(_HDF5) or head.startswith(_NETCDF3):
        if suffix != ".nc":
            raise ParameterError(f"{path} is a NetCDF file but its name does not end in .nc; rename it")
        return "netcdf"
    from ..io import CSV_COLUMNS

    first = head.split(b"\n", 1)[0].strip()
    if first == ",".join(CSV_COLUMNS).encode():
        if suffix != ".csv":
            raise ParameterError(f"{path} is a trajectory CSV file but its name does not end in .csv; rename it")
        return "csv"
    if head.lstrip()[:1] in (b"{", b"["):
        raise ParameterError(f"{path} is a JSON export (of `--out FILE.json` or `--format json`), which keeps only part "
                             "of a result; to read a result back, write it with to_netcdf() or `--out FILE.nc`")
    if b"," in first and b"\0" not in head:
        raise ParameterError(f"{path} is a CSV table without how it was made (header {first[:60].decode(errors='replace')!r}); "
                             "only trajectories are read back from CSV: write other results with to_netcdf() or "
                             "`--out FILE.nc`")
    raise ParameterError(f"{path} is not a result file of skewpend (neither NetCDF, a Zarr store nor a trajectory CSV)")


def _netcdf_kind(path: Path) -> Any:
    from ..errors import require

    netCDF4 = require("netCDF4", "reading .nc")
    try:
        with netCDF4.Dataset(path) as ds:
            return ds.getncattr("kind") if "kind" in ds.ncattrs() else None
    except (OSError, RuntimeError, KeyError) as exc:
        raise ParameterError(f"{path} is not a readable NetCDF file, or is truncated "
                             f"({str(exc).strip() or type(exc).__name__})") from None


def _zarr_kind(path: Path) -> Any:
    from ..numeric.store import require_zarr

    zarr = require_zarr()
    try:
        attrs = dict(zarr.open_group(str(path), mode="r").attrs)
    except Exception:  # noqa: BLE001 - whatever Zarr raises for a damaged group
        raise ParameterError(f"{path} is a damaged Zarr store: its group metadata cannot be read") from None
    if "skewpend_store" not in attrs:
        raise ParameterError(f"{path} is a Zarr store, but not one made by skewpend")
    return attrs.get("kind")


def _csv_has_metadata(path: Path) -> bool:
    """A trajectory CSV has its metadata file beside it (``run.csv.json``; an older skewpend's CSV
    ends with ``# key: value`` lines): the ``kind`` in it."""
    from ..io import has_trajectory_metadata

    return has_trajectory_metadata(path)


# -- helpers -----------------------------------------------------------------------------------------
def _json_attr(attrs: Dict[str, Any], key: str) -> Any:
    return json.loads(str(attrs[key]))


def _protocol(path: Path, attrs: Dict[str, Any]) -> Dict[str, Any]:
    """``params``, ``settings``, ``stats``, ``status``, ``message`` of a file the result protocol wrote."""
    try:
        params = Parameters.from_mapping(_json_attr(attrs, "params"))
    except SkewpendError as exc:
        raise ParameterError(f"{path}: its parameters cannot be read back ({exc})") from None
    return {"params": params, "settings": _json_attr(attrs, "settings"), "stats": _json_attr(attrs, "stats"),
            "status": Status.of(int(attrs["status"])), "message": str(attrs["message"])}


def _agree(path: Path, what: str, stored, rebuilt, *, scale: float = 0.0) -> None:
    """Refuse ``stored`` unless it equals ``rebuilt`` to :data:`AGREEMENT` of their scale (NaN
    where NaN)."""
    a = np.asarray(stored, dtype=complex if np.iscomplexobj(stored) or np.iscomplexobj(rebuilt) else float)
    b = np.asarray(rebuilt, dtype=a.dtype)
    if a.shape != b.shape:
        raise ParameterError(f"{path} was written by another model: its {what} has shape {a.shape}, the parameters "
                             f"give {b.shape}")
    nan_a, nan_b = np.isnan(a), np.isnan(b)
    finite = np.isfinite(a) & np.isfinite(b)
    both_inf = np.isinf(a) & np.isinf(b) & (a == b)
    size = max(scale, float(np.max(np.abs(a[finite]))) if finite.any() else 0.0, 1e-300)
    diff = float(np.max(np.abs(a[finite] - b[finite]))) if finite.any() else 0.0
    if np.any(nan_a != nan_b) or not np.all(finite | both_inf | (nan_a & nan_b)) or diff > AGREEMENT * size:
        raise ParameterError(
            f"{path} was written by another model: its {what} differs from what its parameters give "
            f"(by {diff:.3g}, more than {AGREEMENT:g} of {size:.3g}); it cannot be read back with these equations")


def _energy_function(params: Parameters) -> Callable[[np.ndarray], np.ndarray]:
    """``H(y) = T + Pi - tau . q`` of states ``y`` (n, 4), from the model's kernel."""
    from ..numeric.kernels import kernel_module, parameter_vector

    kernel = kernel_module(params)
    p = parameter_vector(params)
    tau = np.array([params.tau1, params.tau2], dtype=float)

    def H(y: np.ndarray) -> np.ndarray:
        y = np.atleast_2d(np.asarray(y, dtype=float))
        return kernel.energies(y, p) - y[:, :2] @ tau

    return H


# -- the readers of this module ------------------------------------------------------------------------
def _lyapunov_spectrum(path, variables, attrs):
    from .lyapunov import LyapunovSpectrum

    return LyapunovSpectrum(
        exponents=np.asarray(variables["exponent"], dtype=float), uncertainty=np.asarray(variables["uncertainty"], dtype=float),
        t=np.asarray(variables["time"], dtype=float), history=np.asarray(variables["history"], dtype=float),
        window_exponents=np.asarray(variables["window_exponent"], dtype=float), y0=np.asarray(variables["y0"], dtype=float),
        **_protocol(path, attrs))


def _modes(path, variables, attrs):
    from ..errors import EquilibriumError
    from .modes import normal_modes

    proto = _protocol(path, attrs)
    params = proto["params"]
    eq = tuple(float(x) for x in proto["settings"].get("equilibrium", (0.0, 0.0)))
    coulomb = proto["settings"].get("coulomb", "smoothed")  # recorded since the default is "exclude"; before: smoothed
    pairs = np.asarray(variables["eigenvalue_real"], dtype=float) + 1j * np.asarray(variables["eigenvalue_imag"], dtype=float)
    try:
        if eq == (0.0, 0.0):
            try:
                rebuilt = normal_modes(params, coulomb=coulomb)
            except EquilibriumError:
                rebuilt = normal_modes(params, about=eq, coulomb=coulomb)
        else:
            rebuilt = normal_modes(params, about=eq, coulomb=coulomb)
    except SkewpendError as exc:
        raise ParameterError(f"{path} was written by another model: its parameters give no modes there ({exc})") from None
    stored = {"M": variables["M0"], "C": variables["C0"], "K": variables["K0"], "frequencies": variables["frequency"],
              "periods": variables["period"], "shapes": variables["shape"], "damping_ratios": variables["damping_ratio"],
              "damped_frequencies": variables["damped_frequency"], "growth_rates": variables["growth_rate"]}
    stored = {k: np.asarray(v, dtype=float) for k, v in stored.items()}
    for name, value in stored.items():
        _agree(path, name, value, getattr(rebuilt, name))
    _agree(path, "eigenvalues", pairs, rebuilt.eigenvalue_pairs)
    return dataclasses.replace(rebuilt, **stored, eigenvalue_pairs=pairs, eigenvalues=pairs[:, 0].copy(), equilibrium=eq)


def _sweep(path, variables, attrs):
    from .modes import sweep

    proto = _protocol(path, attrs)
    settings = proto["settings"]
    values = np.asarray(variables["value"], dtype=float)
    name = str(settings["swept"])
    try:
        rebuilt = sweep(proto["params"], name, values, tolerance=float(settings["resonance_tolerance"]))
    except SkewpendError as exc:
        raise ParameterError(f"{path} was written by another model: its parameters give no sweep there ({exc})") from None
    freqs = np.column_stack([variables["omega1"], variables["omega2"]]).astype(float)
    shapes = np.empty((values.size, 2, 2))
    for k in (0, 1):
        shapes[:, 0, k] = variables[f"mode{k + 1}_phi"]
        shapes[:, 1, k] = variables[f"mode{k + 1}_psi"]
    _agree(path, "frequencies", freqs, rebuilt.frequencies)
    _agree(path, "mode shapes", shapes, rebuilt.shapes)
    return dataclasses.replace(rebuilt, values=values, frequencies=freqs, shapes=shapes)


def _equilibria(path, variables, attrs):
    from .equilibria import Equilibria, equilibrium_at, wrap

    proto = _protocol(path, attrs)
    params = proto["params"]
    labels = [s.strip() for s in str(attrs.get("labels", "")).split(",") if s.strip()]
    phi, psi = (np.asarray(variables[k], dtype=float).reshape(-1) for k in ("phi", "psi"))
    if len(labels) != phi.size:
        raise ParameterError(f"{path} is not equilibria made by skewpend: {len(labels)} labels for {phi.size} points")
    points = []
    for i in range(phi.size):
        q = (float(phi[i]), float(psi[i]))
        try:
            e = equilibrium_at(params, q)
        except SkewpendError:
            raise ParameterError(f"{path} was written by another model: ({q[0]:.6g}, {q[1]:.6g}) is not an equilibrium "
                                 f"of its parameters") from None
        freq = np.asarray(variables["frequency"], dtype=float)[i]
        grow = np.asarray(variables["growth_rate"], dtype=float)[i]
        stored = {"frequencies": freq[np.isfinite(freq)], "growth_rates": grow[np.isfinite(grow)]}
        _agree(path, f"equilibrium {i}'s angles", wrap(np.subtract(e.q, q)), np.zeros(2), scale=math.pi)
        _agree(path, f"equilibrium {i}'s potential", float(variables["potential"][i]), e.potential,
               scale=max(abs(float(variables["potential"][i])), float(np.abs(e.K).max())))
        for name, value in stored.items():
            _agree(path, f"equilibrium {i}'s {name.replace('_', ' ')}", value, getattr(e, name))
        if int(variables["morse_index"][i]) != e.morse_index or labels[i] != e.label:
            raise ParameterError(f"{path} was written by another model: equilibrium {i} is {labels[i]} of index "
                                 f"{int(variables['morse_index'][i])} there, {e.label} of index {e.morse_index} here")
        points.append(dataclasses.replace(e, q=q, potential=float(variables["potential"][i]),
                                          morse_index=int(variables["morse_index"][i]), label=labels[i], **stored))
    return Equilibria(points=points, **proto)


def _orbit_energy_check(path, params, states, energies, what: str) -> None:
    ok = np.all(np.isfinite(states), axis=1) & np.isfinite(energies)
    if ok.any():
        H = _energy_function(params)(states[ok])
        _agree(path, f"{what} energy", np.asarray(energies)[ok], H)


def _periodic_orbit(path, variables, attrs):
    from .orbits import PeriodicOrbit

    proto = _protocol(path, attrs)
    state = np.asarray(variables["state"], dtype=float)
    energy = float(variables["energy"])
    mono = np.asarray(variables["monodromy"], dtype=float)
    orbit = PeriodicOrbit(state=state, period=float(variables["period"]), energy=energy,
                          rotation=tuple(int(r) for r in proto["settings"].get("rotation", (0, 0))), monodromy=mono,
                          **proto)
    mu = np.asarray(variables["multiplier_real"], dtype=float) + 1j * np.asarray(variables["multiplier_imag"], dtype=float)
    if np.all(np.isfinite(mono)):
        _agree(path, "Floquet multipliers", mu, orbit.multipliers, scale=1.0)
        _orbit_energy_check(path, proto["params"], state[None, :], np.array([energy]), "orbit's")
    object.__setattr__(orbit, "multipliers", mu)  # exactly as stored (the same values, to rounding)
    return orbit


def _sigma_events(BranchEvent, sigma, frequencies, at_energy: Callable, detail: Callable) -> List[Tuple[int, Any]]:
    """Stability changes between neighbouring orbits: where ``sigma`` crosses +2 (a branch point) or
    -2 (period doubling), interpolated -- the rule of the continuations, applied to the stored sigma."""
    out = []
    for k in range(len(sigma) - 1):
        for level, kind in ((2.0, "branch point"), (-2.0, "period doubling")):
            a, b = sigma[k] - level, sigma[k + 1] - level
            if a * b < 0:
                t = a / (a - b) if a != b else 0.5
                way = "loses" if abs(sigma[k + 1]) > abs(sigma[k]) else "regains"
                out.append((k, BranchEvent(kind, k, at_energy(k, t), float(frequencies[k] + t * (frequencies[k + 1] - frequencies[k])),
                                           detail(k, t, way, level))))
    return out


def _nnm(path, variables, attrs):
    from ..numeric.variational import FlowIntegrator
    from .orbits import BranchEvent, NNMFamily

    proto = _protocol(path, attrs)
    params, settings = proto["params"], proto["settings"]
    energies = np.asarray(variables["energy"], dtype=float)
    periods = np.asarray(variables["period"], dtype=float)
    states = np.asarray(variables["state"], dtype=float).reshape(-1, 4)
    sigma = np.asarray(variables["sigma"], dtype=float)
    mu = (np.asarray(variables["multiplier_real"], dtype=float)
          + 1j * np.asarray(variables["multiplier_imag"], dtype=float)).reshape(-1, 4)
    # the monodromy matrices are not stored: one period of the variational flow from each start
    flow = FlowIntegrator(params, rtol=float(settings.get("rtol", 1e-12)), atol=float(settings.get("atol", 1e-12)))
    monos = np.empty((len(energies), 4, 4))
    for k in range(len(energies)):
        fl = flow(states[k], float(periods[k]))
        if fl.status != Status.SUCCESS:
            raise ParameterError(f"{path}: orbit {k} cannot be integrated again ({fl.status.message})")
        _agree(path, f"orbit {k} (closing after one period)", fl.y, states[k], scale=1.0 + float(np.abs(states[k]).max()))
        monos[k] = fl.stm
    _orbit_energy_check(path, params, states, energies, "orbits'")
    freq = 2 * np.pi / periods
    events = [e for _, e in _sigma_events(
        BranchEvent, sigma, freq, lambda k, t: float(energies[k] + t * (energies[k + 1] - energies[k])),
        lambda k, t, way, level: f"the family {way} stability (a multiplier at {'+' if level > 0 else '-'}1)")]
    # folds (where the energy turns back along the family) are kept in the file's event list only
    text = str(attrs.get("events", ""))
    for m in re.finditer(r"fold at E = ([-+0-9.eEinfa]+) J", text):
        k = next((k for k in range(len(energies) - 1) if f"{energies[k + 1]:.9g}" == m.group(1)), None)
        if k is None:
            raise ParameterError(f"{path} is not a nonlinear normal mode made by skewpend: its fold at E = {m.group(1)} J "
                                 "is not one of its orbits")
        events.append(BranchEvent("fold", k, float(energies[k + 1]), float(freq[k + 1]), "the energy turns back along the family"))
    events.sort(key=lambda e: (e.index, e.kind == "fold"))
    rebuilt_text = "; ".join(f"{e.kind} at E = {e.energy:.9g} J" for e in events)
    if rebuilt_text != text:
        raise ParameterError(f"{path} is not a nonlinear normal mode made by skewpend: its events ({text!r}) do not follow "
                             f"from its orbits ({rebuilt_text!r})")
    family = NNMFamily(mode=int(attrs["mode"]), linear_frequency=float(attrs["linear_frequency"]), energies=energies,
                       periods=periods, states=states, monodromies=monos, events=events,
                       energy_max=float(settings.get("energy_max", energies[-1] if energies.size else math.nan)), **proto)
    _agree(path, "sigma (trace of the monodromy - 2)", sigma, family.sigma, scale=4.0)
    _agree(path, "Floquet multipliers", mu, family.multipliers, scale=1.0)
    object.__setattr__(family, "sigma", sigma)  # exactly as stored (the same values, to rounding)
    object.__setattr__(family, "multipliers", mu)
    return family


def _nnm_alpha(path, variables, attrs):
    from .orbits import AlphaFamily, BranchEvent

    proto = _protocol(path, attrs)
    params = proto["params"]
    alphas = np.asarray(variables["alpha"], dtype=float)
    periods = np.asarray(variables["period"], dtype=float)
    states = np.asarray(variables["state"], dtype=float).reshape(-1, 4)
    sigma = np.asarray(variables["sigma"], dtype=float)
    energy = float(attrs["energy"])
    for a, y in zip(alphas, states):
        _orbit_energy_check(path, params.replace(alpha=float(a)), y[None, :], np.array([energy]),
                            f"orbit's at alpha = {a:.6g} rad")
    freq = 2 * np.pi / periods
    events = [e for _, e in _sigma_events(
        BranchEvent, sigma, freq, lambda k, t: energy,
        lambda k, t, way, level: f"at alpha = {math.degrees(alphas[k] + t * (alphas[k + 1] - alphas[k])):.4g} deg the orbit "
                                 f"{way} stability")]
    return AlphaFamily(mode=int(attrs["mode"]), energy=energy, alphas=alphas, periods=periods, states=states, sigma=sigma,
                       events=events, **proto)


def _poincare(path, variables, attrs):
    from ..numeric.kernels import kernel_module, parameter_vector
    from .poincare import PoincareSection, mass_matrices

    proto = _protocol(path, attrs)
    params, settings = proto["params"], proto["settings"]
    name = str(settings["coordinate"])
    c = 0 if name == "phi" else 1
    o = 1 - c
    other = ("psi", "phi")[c]
    q = np.asarray(variables[other], dtype=float)
    p = np.asarray(variables[f"p_{other}"], dtype=float)
    dq = np.asarray(variables[f"d{other}"], dtype=float)
    error = np.asarray(variables["energy_error"], dtype=float)
    # the full states: the section joint at the section (its angle wrapped), its speed from the
    # other joint's momentum p = M_oc q_c' + M_oo q_o' (or, where M_oc vanishes, from the energy)
    kernel = kernel_module(params, chaos=True)
    pv = parameter_vector(params)
    states = np.zeros((q.size, 4))
    states[:, c] = math.remainder(float(settings["value"]), 2 * math.pi)
    states[:, o] = q
    states[:, 2 + o] = dq
    if q.size:
        M = mass_matrices(kernel, pv, states[:, :2])
        Moc, Moo, Mcc = M[:, o, c], M[:, o, o], M[:, c, c]
        coupled = np.abs(Moc) > 1e-6 * np.sqrt(np.abs(Moo * Mcc))
        with np.errstate(all="ignore"):
            states[:, 2 + c] = np.where(coupled, (p - Moo * dq) / np.where(coupled, Moc, 1.0), 0.0)
        if not coupled.all():
            H = _energy_function(params)
            kinetic_rest = float(settings["energy"]) + error[~coupled] - H(states[~coupled])  # the section joint's share
            sign = np.where(int(settings.get("direction", 1)) < 0, -1.0, 1.0)
            states[~coupled, 2 + c] = sign * np.sqrt(np.clip(2 * kinetic_rest / Mcc[~coupled], 0.0, None))
        E = _energy_function(params)(states)
        _agree(path, "crossings' energy", float(settings["energy"]) + error, E,
               scale=abs(float(settings["energy"]) - float(proto["stats"].get("e_min", 0.0))))
    n_unreachable = int(proto["stats"].get("unreachable", 0))
    return PoincareSection(
        q=q, p=p, dq=dq, t=np.asarray(variables["t"], dtype=float), states=states, energy_error=error,
        orbit=np.asarray(variables["orbit_index"]).astype(np.int64),
        seeds=np.column_stack([variables["seed_q"], variables["seed_p"]]).astype(float),
        crossings=np.asarray(variables["crossings"]).astype(np.int64), orbit_status=np.asarray(variables["status"]).astype(np.int32),
        unreachable=np.full((n_unreachable, 2), np.nan), **proto)


def _identification(path, variables, attrs):
    from .identify import Identification, model_terms, standard_vector

    proto = _protocol(path, attrs)
    try:
        params0 = Parameters.from_mapping(_json_attr(attrs, "params0"))
    except SkewpendError as exc:
        raise ParameterError(f"{path}: its starting parameters cannot be read back ({exc})") from None

    def names(key):
        text = str(attrs.get(key, ""))
        return tuple(x for x in text.split("; ") if x) if text else ()

    def numbers(key):
        return [float(x) for x in np.atleast_1d(np.asarray(attrs.get(key, []), dtype=float))]

    ratio_names = names("ratio_names")
    ratios = dict(zip(ratio_names, numbers("ratios")))
    ratio_iv = {k: (lo, hi) for k, lo, hi in zip(ratio_names, numbers("ratio_lower"), numbers("ratio_upper"))}
    values = np.asarray(variables["value"], dtype=float)
    intervals = np.column_stack([np.asarray(variables["lower"], dtype=float), np.asarray(variables["upper"], dtype=float)])
    alpha_iv = numbers("alpha_interval") or [math.nan, math.nan]
    get = lambda key: np.asarray(variables[key], dtype=float) if key in variables else np.zeros(0)  # noqa: E731
    result = Identification(
        params0=params0, names=names("base_names"), expressions=names("base_expressions"), values=values,
        intervals=intervals, free=names("free"), reference=str(attrs.get("reference", "")) or None, ratios=ratios,
        ratio_intervals=ratio_iv, undetermined=names("undetermined"), not_entering=names("not_entering"),
        pieces=names("pieces"), residual_rms=get("residual_rms"), validation=names("validation"),
        heldout_kind=names("heldout_kind"), heldout_rms=get("heldout_rms"), heldout_rms0=get("heldout_rms0"),
        method=str(attrs.get("method", "linear")), fit_rms=get("fit_rms"),
        alpha=float(attrs.get("alpha", math.nan)), alpha_interval=(alpha_iv[0], alpha_iv[-1]),
        alpha_note=str(attrs.get("alpha_note", "")),
        profile_alpha=np.asarray(variables["profile"], dtype=float) if "profile" in variables else np.zeros(0),
        profile_cost=get("profile_cost"),
        correlation=np.asarray(variables["correlation"], dtype=float) if "correlation" in variables else np.zeros((0, 0)),
        **proto)
    # the stored base parameters are those of the stored model (a model projected onto the nearest
    # physical body, or one that failed, keeps the estimate itself)
    if result.status is Status.SUCCESS and "nearest physical body" not in result.message and len(values):
        p = result.params
        B = model_terms(params0.replace(alpha=None)) if result.settings.get("alpha_free") else model_terms(params0)
        if tuple(B.names) != result.names:
            raise ParameterError(f"{path} was written by another model: its base parameters are {list(result.names)}, "
                                 f"the model's are {list(B.names)}")
        alpha = float(p.alpha) if p.alpha is not None else 0.0
        _agree(path, "base parameters", values, B.values(standard_vector(p), float(p.a), alpha, float(p.g)))
    return result


def _netcdf_reader(kind_reader):
    def read(path: Path, kind: str):
        from ..io import read_netcdf

        variables, attrs = read_netcdf(path, kind=kind)
        try:
            return kind_reader(path, variables, attrs)
        except (KeyError, TypeError, ValueError, IndexError, json.JSONDecodeError) as exc:
            if isinstance(exc, ParameterError):
                raise
            raise ParameterError(f"{path} is not a {kind} made by skewpend (missing or bad {type(exc).__name__}: "
                                 f"{exc})") from None
    return read


def _by_opener(module: str, name: str):
    def read(path: Path, kind: str):
        from importlib import import_module

        return getattr(import_module(module, __package__), name)(path)
    return read


def _trajectory(path: Path, kind: str):
    from ..numeric.simulation import open_trajectory

    traj = open_trajectory(path)
    if not traj.params.is_numeric:
        raise ParameterError(f"{path} is not a trajectory made by skewpend: its parameters are missing")
    for key in SIMULATE_SETTINGS:  # a file leaves out a setting that is None (dt_out when unset)
        traj.settings.setdefault(key, None)
    # the stored energy is the model's at the stored states (a few rows, spread over the run)
    rows = np.unique(np.linspace(0, len(traj.t) - 1, min(len(traj.t), 16)).astype(int))
    from ..numeric.kernels import kernel_module, parameter_vector

    kernel, p = kernel_module(traj.params), parameter_vector(traj.params)
    E = kernel.energies(traj.y[rows], p)
    _agree(path, "energy", traj.energy[rows], E)
    return traj


def _chaos_diagram(path: Path, kind: str):
    from .chaos import open_chaos_diagram

    return open_chaos_diagram(path)  # the caller's parameters: recorded by the store and the file


#: The reader of each result kind (the file attribute ``kind``).
_READERS: Dict[str, Callable[[Path, str], Any]] = {
    "skewpend trajectory": _trajectory,
    "Lyapunov spectrum": _netcdf_reader(_lyapunov_spectrum),
    "Lyapunov map": _by_opener(".lyapunov", "open_lyapunov_map"),
    "normal modes": _netcdf_reader(_modes),
    "modes sweep": _netcdf_reader(_sweep),
    "flip map": _by_opener(".flipmap", "open_flip_map"),
    "equilibria": _netcdf_reader(_equilibria),
    "periodic orbit": _netcdf_reader(_periodic_orbit),
    "nonlinear normal mode": _netcdf_reader(_nnm),
    "nonlinear normal mode along alpha": _netcdf_reader(_nnm_alpha),
    "Poincare section": _netcdf_reader(_poincare),
    "region of attraction": _by_opener(".roa", "open_region_of_attraction"),
    "chaos diagram": _chaos_diagram,
    "identification": _netcdf_reader(_identification),
}


def _store_kinds() -> Dict[str, str]:
    """Zarr store kind -> result kind, from the jobs that write them."""
    from .chaos import STORE_KIND as CHAOS
    from .flipmap import STORE_KIND as FLIP
    from .lyapunov import LyapunovMapJob
    from .roa import STORE_KIND as ROA

    return {FLIP: "flip map", CHAOS: "chaos diagram", LyapunovMapJob.kind: "Lyapunov map", ROA: "region of attraction"}


def result_kinds() -> Tuple[str, ...]:
    """Every result kind :func:`open_result` reads (the file attribute ``kind``)."""
    return tuple(_READERS)


def open_result(path):
    """The result stored at ``path``, whatever its kind: a trajectory (``.nc`` or ``.csv``), a
    Lyapunov spectrum or map, normal modes or a modes sweep, a flip map, equilibria, a periodic
    orbit, a nonlinear normal mode (in energy or along alpha), a Poincare section, a region of
    attraction or a chaos diagram -- written by ``to_netcdf(path)`` (``*.nc``), a complete
    store ``*.zarr`` of a grid computation, or ``simulate(..., out="run.csv")``.

    The container is recognised by its content and the kind by the file's ``kind`` attribute;
    the result comes back as the class that wrote it, with its data, ``params``, ``settings``,
    ``stats``, ``status`` and ``message``.  Parts a file does not hold (the linearisation of
    equilibria, the monodromy matrices of a family of orbits, the full states of a section's
    crossings, ...) are recomputed from the parameters and checked against what is stored (to
    :data:`AGREEMENT` relative): a file written by another model is refused.

    Anything else -- a missing, empty or truncated file, a file or directory skewpend did not
    write, an unknown kind, a JSON or CSV export that keeps only part of a result -- is one
    :class:`~skewpend.errors.ParameterError` line.

    >>> import os, tempfile, skewpend
    >>> path = os.path.join(tempfile.mkdtemp(), "modes.nc")
    >>> modes = skewpend.normal_modes(skewpend.reference_parameters())
    >>> _ = modes.to_netcdf(path)
    >>> back = skewpend.open_result(path)
    >>> type(back).__name__, bool((back.frequencies == modes.frequencies).all())
    ('Modes', True)
    """
    if isinstance(path, bool) or not isinstance(path, (str, bytes)) and not hasattr(path, "__fspath__"):
        raise ParameterError(f"path must be a file name, got {path!r}")
    path = Path(path.decode() if isinstance(path, bytes) else path)
    container = _container(path)
    if container == "netcdf":
        kind = _netcdf_kind(path)
        if kind is None:
            raise ParameterError(f"{path} is a NetCDF file, but not a result of skewpend (it has no 'kind' attribute)")
    elif container == "zarr":
        store_kind = _zarr_kind(path)
        kind = _store_kinds().get(str(store_kind))
        if kind is None:
            raise ParameterError(f"{path} is a skewpend store of kind {store_kind!r}, which open_result cannot read; "
                                 f"it reads stores of {', '.join(sorted(_store_kinds()))}")
    else:
        if not _csv_has_metadata(path):
            raise ParameterError(f"{path} is a trajectory CSV without its metadata file {path.name}.json beside it (how "
                                 "the run was made): keep the two files together")
        kind = "skewpend trajectory"
    reader = _READERS.get(str(kind))
    if reader is None:
        raise ParameterError(f"{path} holds a result of kind {str(kind)!r}, which this version of skewpend cannot read "
                             f"back; known kinds: {', '.join(_READERS)}")
    return reader(path, str(kind))
