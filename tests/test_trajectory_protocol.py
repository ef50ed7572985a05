"""A trajectory speaks the result protocol (issue 15): status as a Status, ok, message,
to_xarray with units, to_netcdf and open_trajectory (and CSV) round trips that give back every
number exactly, and a summary that says how the run ended."""

from __future__ import annotations

import numpy as np
import pytest

import skewpend
from skewpend import ParameterError, Parameters, Status, open_trajectory, simulate

P = Parameters(a=1.0, b=0.8, m1=1.0, m2=0.7, alpha=0.6, g=9.81, c1=0.05, tau2=0.1)
Y0 = (1.2, -0.8, 0.3, 0.0)


@pytest.fixture(scope="module")
def tr():
    return simulate(P, Y0, 3.0, dt_out=0.01)


def test_status_ok_and_message(tr):
    assert tr.status is Status.SUCCESS and tr.ok and tr.success and tr.status == 0
    cut = simulate(P, Y0, 3.0, max_steps=10)
    assert cut.status is Status.MAX_STEPS and not cut.ok and not cut.success
    assert cut.message == Status.MAX_STEPS.message and cut.message in cut.summary() and "taylor" in cut.summary()
    assert "chosen by method 'auto'" in cut.summary()  # the default: it says what it chose


def test_to_xarray_has_every_column_with_units(tr):
    pytest.importorskip("xarray")
    ds = tr.to_xarray()
    np.testing.assert_array_equal(ds["t"].values, tr.t)
    np.testing.assert_array_equal(ds["phi"].values, tr.y[:, 0])
    np.testing.assert_array_equal(ds["dpsi"].values, tr.y[:, 3])
    np.testing.assert_array_equal(ds["energy"].values, tr.energy)
    np.testing.assert_array_equal(np.column_stack([ds[k].values for k in ("x1", "y1", "z1", "x2", "y2", "z2")]),
                                  tr.tips())
    assert ds["phi"].attrs["units"] == "rad" and ds["energy"].attrs["units"] == "J" and ds["x2"].attrs["units"] == "m"
    assert ds.attrs["kind"] == "skewpend trajectory" and ds.attrs["status"] == 0 and ds.attrs["method"] == "taylor"


@pytest.mark.parametrize("suffix", [".nc", ".csv"])
def test_a_written_trajectory_reopens_exactly(tr, tmp_path, suffix):
    if suffix == ".nc":
        pytest.importorskip("netCDF4")
        path = tr.to_netcdf(tmp_path / "run.nc")
    else:
        path = skewpend.io.write_trajectory(tr, tmp_path / "run.csv")
    back = open_trajectory(path)
    for name in ("t", "y", "energy", "work"):
        np.testing.assert_array_equal(getattr(back, name), getattr(tr, name))  # %.17g and float64: exact
    assert back.params == tr.params and back.method == tr.method and back.status is Status.SUCCESS
    assert back.energy_drift == tr.energy_drift and back.stats["steps"] == tr.stats["steps"]
    assert back.settings["rtol"] == tr.settings["rtol"]
    np.testing.assert_array_equal(back.tips(), tr.tips())  # the kernel of the parameters read back


def test_a_streamed_run_reopens_like_a_kept_one(tmp_path):
    pytest.importorskip("netCDF4")
    kept = simulate(P, Y0, 2.0, dt_out=0.05)
    simulate(P, Y0, 2.0, dt_out=0.05, out=tmp_path / "s.nc", keep=False)
    back = open_trajectory(tmp_path / "s.nc")
    np.testing.assert_array_equal(back.y, kept.y)
    np.testing.assert_array_equal(back.t, kept.t)


def test_reopening_something_else_is_one_clear_error(tmp_path):
    (tmp_path / "x.csv").write_text("a,b\n1,2\n")
    with pytest.raises(ParameterError, match="not a skewpend trajectory"):
        open_trajectory(tmp_path / "x.csv")
    with pytest.raises(ParameterError, match="does not exist"):
        open_trajectory(tmp_path / "none.nc")
    with pytest.raises(ParameterError, match=".csv or .nc"):
        open_trajectory(tmp_path / "x.txt")
    tr = simulate(P, Y0, 0.5)
    with pytest.raises(ParameterError, match=".nc"):
        tr.to_netcdf(tmp_path / "x.csv")


def test_a_lyapunov_map_counts_accepted_and_rejected_steps_as_lyapunov_does():
    """stats['steps'] means accepted steps everywhere: the map's cells (sp_lyap1_many) counted
    against lyapunov() of each start (sp_lyap through the driver), which also gives the same
    exponent to the bit."""
    p = Parameters(a=1.0, b=1.0, m1=1.0, m2=1.0, g=9.81, alpha=0.6)
    m = skewpend.lyapunov_map(p, 2, t_end=20.0)
    steps = rejected = 0
    for i in range(2):
        for j in range(2):
            r = skewpend.lyapunov(p, [m.phi0[i, j], m.psi0[i, j], 0.0, 0.0], t_end=20.0, n_exponents=1,
                                  rtol=1e-8, atol=1e-8, renorm_every=1.0)
            assert r.exponents[0] == m.exponent[i, j]
            steps, rejected = steps + r.stats["steps"], rejected + r.stats["rejected"]
    assert (m.stats["steps"], m.stats["rejected"]) == (steps, rejected) and rejected > 0


@pytest.mark.parametrize("how", ["streamed", "written"])
def test_csv_is_plain_numeric_columns_and_its_metadata_is_beside_it(tr, tmp_path, how):
    """issue 36: pandas.read_csv(path) and numpy.genfromtxt(path, delimiter=",", names=True), with no
    options, read exactly the rows as float columns named as the header says -- how the run was made
    is in path.json beside the CSV, which open_trajectory reads back; without it, one clear error."""
    import json
    import shutil

    pd = pytest.importorskip("pandas")
    path = tmp_path / "run.csv"
    if how == "streamed":
        simulate(P, Y0, 3.0, dt_out=0.01, out=path, keep=False)
    else:
        skewpend.io.write_trajectory(tr, path)
    df = pd.read_csv(path)
    arr = np.genfromtxt(path, delimiter=",", names=True)
    assert df.shape == (301, 13) and all(dtype == np.float64 for dtype in df.dtypes)
    assert arr.dtype.names == tuple(df.columns) == skewpend.io.CSV_COLUMNS
    np.testing.assert_array_equal(df["t"].to_numpy(), tr.t)
    np.testing.assert_array_equal(arr["phi"], tr.y[:, 0])
    np.testing.assert_array_equal(df[["phi", "psi", "dphi", "dpsi"]].to_numpy(), tr.y)
    np.testing.assert_array_equal(df["energy"].to_numpy(), tr.energy)
    meta = json.loads((tmp_path / "run.csv.json").read_text())
    assert meta["kind"] == "skewpend trajectory" and meta["csv_rows"] == 301 and meta["setting_rtol"] == 1e-10
    back = open_trajectory(path)
    np.testing.assert_array_equal(back.y, tr.y)
    assert back.params == P and back.method == tr.method and back.settings["method"] == "auto"
    shutil.copy(path, tmp_path / "alone.csv")
    with pytest.raises(ParameterError, match=r"alone.csv: its metadata file alone.csv.json .* is missing"):
        open_trajectory(tmp_path / "alone.csv")
