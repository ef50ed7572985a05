"""The lambdify cache (skewpend.numeric.pyfunctions) and the report's lighter imports.

The printed NumPy functions of the normal modes and the equilibria are kept in the cache
directory; a second process reads them without importing SymPy.  What must hold: the cached
function is the same text as the one lambdify prints, so it gives the same bits; a damaged entry
is made again; a warm report's process never imports SymPy or scipy.stats (their import was a
tenth of its first-run overhead, issue 28 goal 4); the light replacements (the Halton points,
the t and normal quantiles) give SciPy's own numbers.
"""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

import skewpend
from skewpend.analysis import equilibria, modes


_CACHED = (modes._matrix_function, equilibria.linearisation_functions, equilibria._direction_functions)


@pytest.fixture
def empty_cache(tmp_path, monkeypatch):
    """An empty cache directory, and the functions' in-process caches cleared before and after."""
    monkeypatch.setenv("SKEWPEND_CACHE_DIR", str(tmp_path))
    for f in _CACHED:
        f.cache_clear()
    yield tmp_path
    for f in _CACHED:
        f.cache_clear()


def _values():
    p = skewpend.Parameters(a=0.9, b=0.6, m1=1.3, m2=0.7, alpha=0.6, g=9.81, c1=0.02, c2=0.05)
    return p, [0.0 if (n == "alpha" and not p.uses_alpha) else float(getattr(p, n)) for n in modes.SCALAR_NAMES]


def test_cached_functions_are_the_printed_ones(empty_cache):
    """Made (SymPy) and then read back (no SymPy): the same source, the same bits, for each of the
    three functions; the entries are files in the cache's ``python`` folder."""
    p, values = _values()
    geometry = modes._geometry(p)
    first = [np.asarray(x) for x in modes._matrix_function(geometry)(*values)]
    lin_first = equilibria.linearisation_functions(equilibria._geometry_only(p))(*values, 0.4, -1.1)
    dir_first = equilibria._direction_functions(equilibria._geometry_only(p))(*values, 0.4, -1.1)
    files = sorted(x.name.split("_")[0] for x in (empty_cache / "python").glob("*.py"))
    assert files == ["directions", "linear", "linearisation"]
    for f in _CACHED:
        f.cache_clear()
    again = [np.asarray(x) for x in modes._matrix_function(geometry)(*values)]
    lin_again = equilibria.linearisation_functions(equilibria._geometry_only(p))(*values, 0.4, -1.1)
    dir_again = equilibria._direction_functions(equilibria._geometry_only(p))(*values, 0.4, -1.1)
    for a, b in zip(first, again):
        assert np.array_equal(a, b)
    assert repr(lin_first) == repr(lin_again) and repr(dir_first) == repr(dir_again)
    # and the modes' matrices are the physics: M symmetric positive definite, C the damping diagonal
    M, C, K = again
    assert np.allclose(M, M.T, rtol=0, atol=1e-15) and np.all(np.linalg.eigvalsh(M) > 0)
    assert np.allclose(C, np.diag([0.02, 0.05]), rtol=0, atol=1e-15)


def test_friction_and_rotor_terms_read_back_the_same(empty_cache):
    """The optional terms (Coulomb friction's atan, the rotor) print other NumPy functions: read back,
    the same bits; the linearised damping is c + cf cfs (the friction's slope at rest)."""
    p = skewpend.Parameters(a=0.9, b=0.6, m1=1.3, m2=0.7, alpha=0.6, g=9.81, c1=0.02, c2=0.05, cf1=0.03, cf2=0.01,
                            Ir=1e-4, gr=-6.0)
    values = [0.0 if (n == "alpha" and not p.uses_alpha) else float(getattr(p, n)) for n in modes.SCALAR_NAMES]
    geometry = modes._geometry(p)
    first = [np.asarray(x) for x in modes._matrix_function(geometry)(*values)]
    lin_first = equilibria.linearisation_functions(equilibria._geometry_only(p))(*values, 0.3, 0.2)
    modes._matrix_function.cache_clear()
    equilibria.linearisation_functions.cache_clear()
    again = [np.asarray(x) for x in modes._matrix_function(geometry)(*values)]
    lin_again = equilibria.linearisation_functions(equilibria._geometry_only(p))(*values, 0.3, 0.2)
    assert all(np.array_equal(a, b) for a, b in zip(first, again))
    assert repr(lin_first) == repr(lin_again)
    C = again[1]
    assert np.allclose(np.diag(C), [0.02 + 0.03 * p.cfs, 0.05 + 0.01 * p.cfs], rtol=1e-14, atol=0)


def test_a_damaged_entry_is_made_again(empty_cache):
    p, values = _values()
    geometry = modes._geometry(p)
    good = [np.asarray(x) for x in modes._matrix_function(geometry)(*values)]
    (entry,) = (empty_cache / "python").glob("linear_matrices_*.py")
    entry.write_text("def _lambdifygenerated(:\n")  # a truncated write
    modes._matrix_function.cache_clear()
    again = [np.asarray(x) for x in modes._matrix_function(geometry)(*values)]
    assert all(np.array_equal(a, b) for a, b in zip(good, again))
    assert "def _lambdifygenerated(" in entry.read_text() and "(:" not in entry.read_text()


def test_another_geometry_is_another_entry(empty_cache):
    p, values = _values()
    modes._matrix_function(modes._geometry(p))
    bent = p.replace(com2=(0.0, 0.35, 0.0))
    modes._matrix_function(modes._geometry(bent))
    assert len(list((empty_cache / "python").glob("linear_matrices_*.py"))) == 2


def test_halton_points_are_scipys():
    from scipy.stats import qmc

    from skewpend.analysis.poincare import halton2

    sampler = qmc.Halton(d=2, scramble=False)
    sampler.fast_forward(1)
    assert np.array_equal(sampler.random(100), halton2(1, 100))
    assert np.array_equal(sampler.random(1000), halton2(101, 1000))


def test_quantiles_are_scipy_stats():
    from scipy.stats import norm, t

    from skewpend.results import normal_quantile as _normal_quantile, t_quantile as _t_quantile

    for dof in (1, 2, 4, 9, 30, 200):
        for q in (0.025, 0.9, 0.975, 0.995):
            assert _t_quantile(q, dof) == pytest.approx(float(t.ppf(q, dof)), rel=1e-14, abs=0)
    assert _normal_quantile(0.975) == pytest.approx(float(norm.ppf(0.975)), rel=1e-14, abs=0)


def test_warm_modes_process_imports_no_sympy(tmp_path):
    """After a first process has filled the cache, a second computes the normal modes and the
    equilibria without importing SymPy or scipy.stats."""
    env = {**os.environ, "SKEWPEND_CACHE_DIR": str(tmp_path)}
    code = ("import sys, skewpend; from skewpend.analysis.modes import normal_modes; "
            "from skewpend.analysis.equilibria import equilibria; "
            "p = skewpend.Parameters(a=1.0, b=0.8, m1=1.0, m2=0.5, alpha=0.7, g=9.81); "
            "m = normal_modes(p); e = equilibria(p); "
            "print(sorted(n for n in ('sympy', 'scipy.stats') if n in sys.modules), "
            "' '.join(f'{w:.15e}' for w in m.frequencies))")
    runs = [subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=300)
            for _ in range(2)]
    for r in runs:
        assert r.returncode == 0, r.stderr
    first, second = (r.stdout.split("] ") for r in runs)
    assert second[0] + "]" == "[]"
    assert first[1] == second[1]  # the same frequencies, digit for digit
