"""Every result speaks one protocol (skewpend.results): status, message, ok, params, settings,
stats, to_xarray, to_netcdf (read back), summary -- and says so when it is partly failed."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from skewpend.status import Status

from skewpend.config import reference_parameters  # noqa: E402
BENCH = reference_parameters()  # the reference case: a = 1, b = 0.8, m1 = 1, m2 = 0.7, alpha = 0.6, g = 9.81


def _results():
    from skewpend.analysis.chaos import chaos_diagram
    from skewpend.analysis.flipmap import flip_map
    from skewpend.analysis.lyapunov import lyapunov, lyapunov_map
    from skewpend.analysis.modes import normal_modes, sweep
    from skewpend.analysis.poincare import poincare

    return {
        "flip map": lambda: flip_map(BENCH, 8, t_end=2.0),
        "Lyapunov map": lambda: lyapunov_map(BENCH, 4, t_end=3.0),
        "chaos diagram": lambda: chaos_diagram(BENCH, alpha=[0.0, 0.5], energy=[5.0], samples=2, t_end=4.0),
        "Lyapunov spectrum": lambda: lyapunov(BENCH, [1.0, 0.5, 0.0, 0.0], t_end=5.0),
        "Poincare section": lambda: poincare(BENCH, energy=8.0, n_orbits=2, n_crossings=5),
        "normal modes": lambda: normal_modes(BENCH),
        "modes sweep": lambda: sweep(BENCH, "alpha", np.linspace(0.0, 1.0, 5)),
    }


@pytest.mark.parametrize("kind", list(_results()))
def test_every_result_speaks_the_protocol(kind, tmp_path):
    xr = pytest.importorskip("xarray")
    pytest.importorskip("netCDF4")
    r = _results()[kind]()
    assert r.result_kind == kind
    assert r.status is Status.SUCCESS and r.ok and isinstance(r.message, str) and r.message
    assert isinstance(r.settings, dict) and isinstance(r.stats, dict) and r.params == BENCH.replace(alpha=r.params.alpha)
    assert kind in r.summary()
    ds = r.to_xarray()
    assert ds.attrs["kind"] == kind and ds.attrs["status"] == 0 and json.loads(ds.attrs["settings"]) is not None
    path = r.to_netcdf(tmp_path / "r.nc")
    assert [p.name for p in tmp_path.iterdir()] == ["r.nc"]
    with xr.open_dataset(path) as back:
        assert back.attrs["kind"] == kind
        for name in ds.data_vars:  # every variable read back as written (NaN in the same places)
            np.testing.assert_array_equal(back[name].values, ds[name].values)


def test_settings_in_files_are_strict_json(tmp_path):
    """No bare NaN in any JSON a result writes (JSON has none)."""
    from skewpend.analysis.lyapunov import lyapunov

    spec = lyapunov(BENCH, [1.0, 0.5, 0.0, 0.0], t_end=3.0, windows=1)
    assert not np.isfinite(spec.uncertainty).any()
    text = json.dumps(spec.to_dict(), allow_nan=False)  # raises on NaN
    assert json.loads(text)["uncertainty"] == [None] * 4
    assert "nan" not in spec.table().lower() and "at least 2 windows" in spec.table()


def test_a_section_off_its_energy_surface_is_partial():
    """A far too loose tolerance: the points do not lie on the energy surface -- the section says so."""
    from skewpend.analysis.poincare import MAX_RELATIVE_ENERGY_ERROR, poincare

    sec = poincare(BENCH, energy=8.0, n_orbits=2, n_crossings=20, rtol=1e-2)  # DOP853 at 1e-2: errors ~0.1 J
    room = 8.0 - sec.stats["e_min"]
    assert sec.stats["max_energy_error"] > MAX_RELATIVE_ENERGY_ERROR * room
    assert sec.status is Status.PARTIAL and not sec.ok and "left the energy surface" in sec.message
    worst = poincare(BENCH, energy=8.0, n_orbits=2, n_crossings=20, rtol=1.0)
    assert worst.status is Status.PARTIAL and "nan" not in worst.message.lower()
    good = poincare(BENCH, energy=8.0, n_orbits=2, n_crossings=20)
    assert good.ok and good.stats["max_energy_error"] < 1e-6 * room


def test_orbits_short_of_their_crossings_are_said():
    from skewpend.analysis.poincare import poincare

    sec = poincare(BENCH, energy=8.0, n_orbits=2, n_crossings=50, t_max=3.0)
    assert sec.status is Status.SHORT and not sec.ok and "reached t_max" in sec.message
    assert np.all(sec.orbit_status == int(Status.SHORT)) and np.all(sec.crossings < 50)


def test_a_status_from_c_is_a_status():
    from skewpend.analysis.lyapunov import lyapunov

    spec = lyapunov(BENCH, [1.0, 0.5, 0.0, 0.0], t_end=50.0, max_steps=100, throw=False)
    assert spec.status is Status.MAX_STEPS and not spec.ok and math.isfinite(spec.stats["t_reached"])


def test_fewer_starts_than_asked_are_said():
    """Starts that cannot be placed are counted and named in the message, never dropped silently."""
    from skewpend.analysis.chaos import chaos_diagram
    from skewpend.analysis.poincare import poincare

    d = chaos_diagram(BENCH, alpha=[0.0], energy=[1e-6, 5.0], samples=4, t_end=4.0)  # 1 uJ: a tiny region
    assert d.stats["unreachable"] == 2 and "2 of the 8 starts" in d.message and d.stats["trajectories"] == 6
    given = poincare(BENCH, energy=8.0, seeds=[(0.1, 0.0), (3.0, 50.0)], n_crossings=5)
    assert given.unreachable.shape == (1, 2) and given.status is Status.SHORT
    assert "only 1 of the 2 orbits" in given.message


def test_the_flip_time_of_one_start_is_the_maps_cell():
    """flip_time (the report's single start) computes a cell exactly as the map does: same bits."""
    from skewpend.analysis.flipmap import flip_map, flip_time

    fm = flip_map(BENCH, 8, t_end=6.0)
    margin = fm.energy_margin()
    assert margin.shape == (8, 8) and np.array_equal(margin < 0, np.isnan(fm.flip_time) & (margin < 0))
    checked = 0
    for i, j in [(0, 0), (1, 6), (3, 3), (7, 2), (5, 5)]:
        one = flip_time(BENCH, fm.phi0[i, j], fm.psi0[i, j], t_end=6.0)
        assert one.forbidden == (margin[i, j] < 0)
        if not one.forbidden:
            assert one.which == fm.which[i, j] and (np.isnan(one.time) and np.isnan(fm.flip_time[i, j])
                                                    or one.time == fm.flip_time[i, j])
            checked += 1
    assert checked >= 2
    with pytest.raises(Exception, match="within"):
        flip_time(BENCH, 4.0, 0.0)
