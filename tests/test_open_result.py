"""``skewpend.open_result``: every result kind written is read back whole, as the class that wrote
it -- data exactly, how it was made (params, settings, stats, status, message) -- and its methods
work; what a file does not hold is rebuilt and checked against the parameters; everything else is
one clear ParameterError line."""

from __future__ import annotations

import json
import math
import shutil
from pathlib import Path

import numpy as np
import pytest

import skewpend as sp
from skewpend import ParameterError, open_result
from skewpend.analysis.readback import AGREEMENT, result_kinds
from skewpend.results import canonical_json

netCDF4 = pytest.importorskip("netCDF4")
xr = pytest.importorskip("xarray")

#: Kinds an earlier skewpend wrote that open_result reads as today's kind: a chain's flip map (a FlipMap
#: since issue 52, when the two flip maps became one).
FORMER = {"chain flip map": "flip map"}


@pytest.fixture(scope="module")
def damped(reference):
    """Damping and torques: complex mode pairs, equilibria away from the hanging one."""
    return reference.replace(c1=0.05, c2=0.03, tau1=0.4, tau2=-0.2)


@pytest.fixture(scope="module")
def results(reference, damped):
    """One small result of every kind (conservative ones from the reference case)."""
    P = reference
    fam = sp.nnm(P, mode=1, energy_max=0.5, resolution=5)
    return {
        "skewpend trajectory": sp.simulate(damped, (1.0, 0.5, 0.2, -0.1), 1.0),
        "Lyapunov spectrum": sp.lyapunov(P, (1.0, 0.5, 0, 0), t_end=5.0),
        "Lyapunov map": sp.lyapunov_map(P, 4, t_end=2.0),
        "normal modes": sp.normal_modes(damped.replace(tau1=0.0, tau2=0.0)),
        "modes sweep": sp.sweep(P, "alpha", np.linspace(0.0, 1.0, 5)),
        "flip map": sp.flip_map(P, 4, t_end=2.0),
        "chain flip map": sp.flip_map(_chain(), 4, plane=("q1", "q3"), held=[0.0, 0.3, 0.0], t_end=2.0),
        "equilibria": sp.equilibria(damped),
        "periodic orbit": fam.orbit(len(fam) - 1),
        "nonlinear normal mode": fam,
        "nonlinear normal mode along alpha": sp.nnm_alpha(P, 1, energy=0.2, alphas=[P.alpha, P.alpha + 0.05]),
        "Poincare section": sp.poincare(P, 1.0, n_orbits=3, n_crossings=10),
        "region of attraction": sp.region_of_attraction(P, n=4, t_end=1.0),
        "chaos diagram": sp.chaos_diagram(P, n_alpha=2, n_energy=2, samples=2, t_end=5.0),
        "identification": _identification(damped.replace(tau1=0.0, tau2=0.0)),
    }


def _chain():
    return sp.Chain.from_lists(3, length=[0.5, 0.4, 0.3], mass=[1.0, 0.8, 0.5], axis=[(0, 0, 1), (0.5, 0, 1), (1, 0, 0)])


def _identification(P):
    """The linear estimate on three noiseless free swings of 1 s made by skewpend (held out: a fourth)."""
    pieces = []
    for i, y0 in enumerate([(1.0, 0.5, 0.0, 0.0), (-0.8, 1.5, 1.0, 0.0), (2.0, -1.0, 0.0, 2.0), (0.5, 0.5, -1.0, 1.0)]):
        tr = sp.simulate(P, y0, 1.0, dt_out=1e-3)
        pieces.append({"t": np.asarray(tr.t), "q": np.asarray(tr.y)[:, :2], "dq": np.asarray(tr.y)[:, 2:], "name": f"s{i}"})
    m = sp.Measurements.from_arrays(pieces, skip=("mean",))
    fit, held = m.split([3])
    return sp.identify(fit, P, validation=held, method="linear", smoothing=0.02)


def test_every_kind_is_covered(results):
    assert set(result_kinds()) == set(results) and len(results) == 15
    for kind, r in results.items():
        assert r.result_kind == FORMER.get(kind, kind)


def _writers():
    """``(module, class, kind, top-level functions of the module)`` of every class of the package
    that writes a result file: it supplies the result protocol's ``_dataset`` or declares its
    ``result_kind`` (read from the source, a top-level class at a time; a kind that is not a
    literal, from the class itself)."""
    import importlib
    import re

    root = Path(sp.__file__).parent
    found = []
    for path in sorted(root.rglob("*.py")):
        text = path.read_text()
        if "_dataset" not in text and "result_kind" not in text:
            continue
        module = ".".join(("skewpend", *path.relative_to(root).with_suffix("").parts))
        functions = set(re.findall(r"^def (\w+)\(", text, re.M))
        for block in re.split(r"^(?=class )", text, flags=re.M)[1:]:
            name = re.match(r"class (\w+)", block)[1]
            body = re.split(r"^(?=\S)", block.split("\n", 1)[1], maxsplit=1, flags=re.M)[0]  # up to the next top-level line
            kind = re.search(r"^    result_kind: ClassVar\[str\] = (.+)$", body, re.M)
            if name == "ResultProtocol" or not (kind or re.search(r"^    def _dataset\(", body, re.M)):
                continue
            assert kind, f"{module}.{name} writes a result file but does not say its result_kind"
            literal = re.fullmatch(r'"([^"]+)"', kind[1].strip())
            found.append((module, name, literal[1] if literal else getattr(importlib.import_module(module), name).result_kind,
                          functions))
    return found


def test_every_kind_is_read_where_it_is_written():
    """Readers beside writers: the registry has a reader for every kind a class writes, and it is
    a function of that class's own module (xarray's backends: registered by name, imported on use)."""
    from skewpend.analysis.readback import READERS

    writers = _writers()
    assert len(writers) >= 15 - len(FORMER)
    kinds = {kind: (module, name, functions) for module, name, kind, functions in writers}
    assert len(kinds) == len(writers)  # one kind, one class
    assert set(kinds) | set(FORMER) == set(READERS) == set(result_kinds()) and not set(kinds) & set(FORMER)
    for kind, (module, name, functions) in kinds.items():
        where, _, function = READERS[kind].partition(":")
        assert where == module, f"{kind}: written by {module}.{name}, read by {READERS[kind]}"
        assert function in functions, f"{kind}: {module} has no function {function}"


def test_the_door_imports_no_reader():
    """``open_result``'s module imports a reader only when a file of its kind is read: at module
    level it imports nothing of the analyses or the numeric layer (the registry names them)."""
    import ast

    from skewpend.analysis import readback

    tree = ast.parse(Path(readback.__file__).read_text())
    imported = [node.module or "" for node in tree.body if isinstance(node, ast.ImportFrom) and node.level]
    assert imported and all(m.split(".")[0] in ("errors", "results") for m in imported), imported


def _same(back, orig):
    """The same class, how it was made, and every stored array exactly (NaN where NaN)."""
    assert type(back) is type(orig)
    assert back.params == orig.params
    assert back.status == orig.status and back.message == orig.message and back.ok == orig.ok
    assert canonical_json(back.settings) == canonical_json(orig.settings)
    assert canonical_json(back.stats) == canonical_json(orig.stats)
    a, b = orig.to_xarray(), back.to_xarray()
    xr.testing.assert_identical(a, b)  # values bit for bit, coordinates, attributes


def _methods(back):
    assert back.summary().startswith(back.result_kind)
    assert "\n" not in repr(back) and repr(back).startswith(f"<{type(back).__name__}")
    if hasattr(back, "table"):
        assert back.table()


@pytest.mark.parametrize("kind", ["skewpend trajectory", "Lyapunov spectrum", "Lyapunov map", "normal modes",
                                  "modes sweep", "flip map", "chain flip map", "equilibria", "periodic orbit",
                                  "nonlinear normal mode",
                                  "nonlinear normal mode along alpha", "Poincare section", "region of attraction",
                                  "chaos diagram", "identification"])
def test_netcdf_round_trip(results, kind, tmp_path):
    orig = results[kind]
    path = orig.to_netcdf(tmp_path / "result.nc")
    back = open_result(path)
    _same(back, orig)
    _methods(back)
    again = open_result(back.to_netcdf(tmp_path / "again.nc"))  # a reopened result writes the same file
    _same(again, orig)


def test_trajectory_csv(damped, tmp_path):
    orig = sp.simulate(damped, (1.0, 0.5, 0.2, -0.1), 1.0, out=tmp_path / "run.csv")
    back = open_result(tmp_path / "run.csv")
    for name in ("t", "y", "energy", "work"):
        np.testing.assert_array_equal(getattr(back, name), getattr(orig, name))  # %.17g: exact
    assert back.params == orig.params and back.status == orig.status and back.message == orig.message
    np.testing.assert_allclose(back.tips(), orig.tips(), rtol=0, atol=1e-12)
    _methods(back)


@pytest.mark.parametrize("kind, make", [
    ("flip map", lambda P, s: sp.flip_map(P, 4, t_end=2.0, store=s)),
    ("chain flip map", lambda P, s: sp.flip_map(_chain(), 4, plane=("q1", "q3"), t_end=2.0, store=s)),
    ("Lyapunov map", lambda P, s: sp.lyapunov_map(P, 4, t_end=2.0, store=s)),
    ("region of attraction", lambda P, s: sp.region_of_attraction(P, n=4, t_end=1.0, store=s)),
    ("chaos diagram", lambda P, s: sp.chaos_diagram(P, n_alpha=2, n_energy=2, samples=2, t_end=5.0, store=s)),
])
def test_zarr_stores(reference, kind, make, tmp_path):
    pytest.importorskip("zarr")
    orig = make(reference, tmp_path / "grid.zarr")
    back = open_result(tmp_path / "grid.zarr")
    assert type(back) is type(orig) and back.result_kind == FORMER.get(kind, kind)
    for name, var in orig.to_xarray().data_vars.items():
        np.testing.assert_array_equal(back.to_xarray()[name].values, var.values)
    same = back.params == orig.params  # a chaos diagram's store records the caller's (alpha is an axis of its grid)
    assert same and back.status == orig.status
    _methods(back)


# -- what a file does not hold: rebuilt, and equal to the original's ---------------------------------------
def test_rebuilt_parts_match_the_original(results, tmp_path):
    def reopen(kind):
        return open_result(results[kind].to_netcdf(tmp_path / f"{kind.replace(' ', '_')}.nc"))

    modes, orig = reopen("normal modes"), results["normal modes"]
    assert modes.damped and np.iscomplexobj(modes.eigenvalues)
    np.testing.assert_array_equal(modes.eigenvalues, orig.eigenvalues)
    np.testing.assert_allclose(modes.ratios, orig.ratios, rtol=1e-12)
    assert modes.beat_period == pytest.approx(orig.beat_period, rel=1e-12)
    np.testing.assert_allclose(modes.state_matrix, orig.state_matrix, rtol=1e-12, atol=1e-12)

    eq, orig = reopen("equilibria"), results["equilibria"]
    assert [e.label for e in eq] == [e.label for e in orig] and eq.index_sum == orig.index_sum
    for e, o in zip(eq, orig):
        assert e.q == o.q and e.potential == o.potential and e.morse_index == o.morse_index
        for name in ("M", "C", "K", "A", "eigenvalues", "shapes", "unstable_directions"):
            np.testing.assert_allclose(getattr(e, name), getattr(o, name), rtol=1e-9, atol=1e-9)
    assert sp.normal_modes(eq.params, about=eq[0]).ok  # the rebuilt linearisation serves the modes

    sw, orig = reopen("modes sweep"), results["modes sweep"]
    assert sw.resonances == orig.resonances
    np.testing.assert_allclose(sw.ratios, orig.ratios, rtol=1e-12)

    fam, orig = reopen("nonlinear normal mode"), results["nonlinear normal mode"]
    np.testing.assert_allclose(fam.monodromies, orig.monodromies, rtol=0, atol=1e-9)
    assert fam.events == orig.events and fam.energy_max == orig.energy_max
    k = len(fam) // 2
    assert fam.orbit(k).stable == orig.orbit(k).stable and fam.at_energy(0.3).period == orig.at_energy(0.3).period

    alpha, orig = reopen("nonlinear normal mode along alpha"), results["nonlinear normal mode along alpha"]
    assert alpha.events == orig.events
    np.testing.assert_array_equal(alpha.stable, orig.stable)

    orbit, orig = reopen("periodic orbit"), results["periodic orbit"]
    assert orbit.rotation == orig.rotation and orbit.sigma == orig.sigma and orbit.stable == orig.stable

    sec, orig = reopen("Poincare section"), results["Poincare section"]
    wrapped = orig.states.copy()
    wrapped[:, :2] = np.mod(wrapped[:, :2] + math.pi, 2 * math.pi) - math.pi
    np.testing.assert_allclose(sec.states, wrapped, rtol=0, atol=1e-9)
    for a, b in zip(sec.boundary(), orig.boundary()):
        np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(sec.orbit_points(1)[0], orig.orbit_points(1)[0])

    lyap = reopen("Lyapunov spectrum")
    np.testing.assert_equal(lyap.kaplan_yorke_dimension, results["Lyapunov spectrum"].kaplan_yorke_dimension)


def test_a_failed_orbit_round_trips(reference, tmp_path):
    bad = sp.periodic_orbit(reference, (2.5, -2.0, 3.0, -4.0), 0.37, max_iterations=3)
    assert not bad.ok
    back = open_result(bad.to_netcdf(tmp_path / "bad.nc"))
    _same(back, bad)
    assert back.table().startswith("no periodic orbit")


# -- another model: refused -------------------------------------------------------------------------------
def _edit_attr(path, name, value):
    with netCDF4.Dataset(path, "a") as ds:
        ds.setncattr(name, value)


@pytest.mark.parametrize("kind", ["normal modes", "modes sweep", "equilibria", "periodic orbit",
                                  "nonlinear normal mode", "nonlinear normal mode along alpha", "Poincare section"])
def test_a_file_of_another_model_is_refused(results, kind, tmp_path):
    path = results[kind].to_netcdf(tmp_path / "result.nc")
    params = results[kind].params.to_dict()
    params["m2"] = float(params["m2"]) * 1.5
    _edit_attr(path, "params", canonical_json(params))
    with pytest.raises(ParameterError, match="another model") as err:
        open_result(path)
    assert "\n" not in str(err.value)


def test_a_trajectory_of_another_model_is_refused(results, tmp_path):
    path = results["skewpend trajectory"].to_netcdf(tmp_path / "run.nc")
    _edit_attr(path, "param_m2", 2.0)
    with pytest.raises(ParameterError, match="another model"):
        open_result(path)


def test_the_agreement_is_stated():
    assert 0 < AGREEMENT <= 1e-6


# -- anything else: one clear line ---------------------------------------------------------------------------
def _refused(path, *fragments):
    with pytest.raises(ParameterError) as err:
        open_result(path)
    text = str(err.value)
    assert "\n" not in text, text
    for f in fragments:
        assert f in text, text
    return text


def test_missing_empty_and_foreign_files(tmp_path, results):
    _refused(tmp_path / "none.nc", "does not exist")
    (tmp_path / "empty.nc").write_bytes(b"")
    _refused(tmp_path / "empty.nc", "empty")
    (tmp_path / "text.nc").write_text("hello\n")
    _refused(tmp_path / "text.nc", "not a result file")
    (tmp_path / "x.json").write_text(json.dumps({"exponents": [0.1]}))
    _refused(tmp_path / "x.json", "JSON export", ".nc")
    (tmp_path / "table.csv").write_text("t,lambda_1\n0,0.1\n")
    _refused(tmp_path / "table.csv", "CSV table")
    with pytest.raises(ParameterError):
        open_result(None)


def test_netcdf_without_kind_or_of_unknown_kind(tmp_path):
    with netCDF4.Dataset(tmp_path / "plain.nc", "w") as ds:
        ds.createDimension("x", 2)
        ds.createVariable("x", "f8", ("x",))[:] = [1, 2]
    _refused(tmp_path / "plain.nc", "not a result of skewpend")
    _edit_attr(tmp_path / "plain.nc", "kind", "weather forecast")
    _refused(tmp_path / "plain.nc", "'weather forecast'", "known kinds")


def test_a_file_missing_what_its_kind_needs(results, tmp_path):
    path = results["normal modes"].to_netcdf(tmp_path / "modes.nc")
    _edit_attr(path, "kind", "equilibria")
    _refused(path, "not a equilibria made by skewpend")
    _edit_attr(path, "kind", "normal modes")
    _edit_attr(path, "params", "{not json")
    _refused(path)


def test_truncated_files(results, tmp_path):
    path = results["equilibria"].to_netcdf(tmp_path / "eq.nc")
    data = path.read_bytes()
    (tmp_path / "cut.nc").write_bytes(data[: len(data) // 2])
    _refused(tmp_path / "cut.nc", "cut.nc")
    run = tmp_path / "run.csv"
    sp.simulate(results["skewpend trajectory"].params, (1.0, 0.5, 0, 0), 0.5, out=run)
    rows = run.read_text().splitlines(keepends=True)
    (tmp_path / "cut.csv").write_text("".join(rows[: len(rows) // 2]))
    _refused(tmp_path / "cut.csv", "cut.csv.json", "keep the two files together")  # the metadata file not copied
    shutil.copy(tmp_path / "run.csv.json", tmp_path / "cut.csv.json")
    _refused(tmp_path / "cut.csv", "truncated")  # the metadata records the rows written


def test_misnamed_files_and_directories(results, tmp_path):
    path = results["normal modes"].to_netcdf(tmp_path / "modes.nc")
    shutil.copy(path, tmp_path / "modes.dat")
    _refused(tmp_path / "modes.dat", "NetCDF", "rename")
    (tmp_path / "folder.zarr").mkdir()
    _refused(tmp_path / "folder.zarr", "not a Zarr store")
    (tmp_path / "plain").mkdir()
    _refused(tmp_path / "plain", "directory")


def test_a_foreign_zarr_store(tmp_path):
    zarr = pytest.importorskip("zarr")
    zarr.open_group(str(tmp_path / "other.zarr"), mode="w").attrs["kind"] = "flip map"
    _refused(tmp_path / "other.zarr", "not one made by skewpend")


def test_the_flip_maps_of_before_issue_52(tmp_path):
    """Files and stores an earlier skewpend wrote (tests/data: 4 x 4 maps of the reference double pendulum and of
    a skewed triple over (q1, q3), q2 held at 0.3 rad, t_end = 2 s) read back as today's FlipMap: the double
    pendulum's as it was, a chain's (kind ``chain flip map``, its joints numbered 1 .. n, 0 none) with ``which``
    the angle's index and its ranges named by the plane; its store and its file alike; a map computed now agrees."""
    import tarfile

    zarr = pytest.importorskip("zarr")
    if int(zarr.__version__.split(".")[0]) < 3:
        pytest.skip("the stores were written by Zarr 3")
    with tarfile.open(Path(__file__).parent / "data" / "flip-maps-before-issue-52.tar.gz") as tar:
        tar.extractall(tmp_path, filter="data")
    with netCDF4.Dataset(tmp_path / "chain.nc") as ds:
        assert ds.getncattr("kind") == "chain flip map"
        stored = np.asarray(ds["which"][...])
    chain = sp.Chain.from_lists(3, length=[0.5, 0.4, 0.3], mass=[1.0, 0.8, 0.5], axis=[(0, 0, 1), (0.5, 0, 1), (1, 0, 0)])
    now = {"chain": sp.flip_map(chain, 4, plane=("q1", "q3"), held=[0.0, 0.3, 0.0], t_end=2.0, workers=1),
           "double": sp.flip_map(sp.reference_parameters(), 4, t_end=2.0, workers=1)}
    for name, fm in now.items():
        nc, store = open_result(tmp_path / f"{name}.nc"), open_result(tmp_path / f"{name}.zarr")
        for back in (nc, store):
            assert type(back) is sp.FlipMap and back.ok and back.params == fm.params and back.plane == fm.plane
            np.testing.assert_array_equal(back.which, fm.which)
            np.testing.assert_allclose(back.flip_time, fm.flip_time, rtol=0, atol=1e-9)
            np.testing.assert_array_equal(back.x0, fm.x0)
            np.testing.assert_array_equal(back.held, fm.held)
            assert back.window() == fm.window() and back.settings["t_end"] == 2.0
        assert nc.flip_time.tobytes() == store.flip_time.tobytes() and canonical_json(nc.settings) == canonical_json(store.settings)
    np.testing.assert_array_equal(open_result(tmp_path / "chain.nc").which, np.where(stored > 0, stored - 1, -1))
    assert sp.open_flip_map(tmp_path / "chain.zarr").settings["q3_range"] == (-math.pi, math.pi)
