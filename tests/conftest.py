"""Test-session set-up: compiled kernels go to a cache inside the project, not the user's; the quick
selection (``-m "not slow"``); the split over pytest-xdist's workers; tools a module needs."""

from __future__ import annotations

import os
from pathlib import Path

os.environ.setdefault("SKEWPEND_CACHE_DIR", str(Path(__file__).resolve().parent.parent / ".skewpend-test-cache"))
# method="auto" takes taylor whatever the cache holds (a first use would otherwise run dop853 while a
# detached process builds the Taylor library): the tests of the rule see one choice; tests/test_first_use.py
# tests the background build itself
os.environ.setdefault("SKEWPEND_TAYLOR_BUILD", "foreground")


import pytest  # noqa: E402


@pytest.fixture(scope="session")
def reference():
    """The reference case (the README's, the report's and ``skewpend simulate``'s built-in model):
    ``skewpend.reference_parameters()``."""
    from skewpend.config import reference_parameters

    return reference_parameters()


@pytest.fixture(scope="session")
def reference_state():
    """The reference case's initial state ``(phi, psi, dphi, dpsi)``."""
    from skewpend.config import reference_state

    return reference_state()


@pytest.fixture
def recursive_forms(monkeypatch):
    """Chains run on the recursive algorithms' forms even where the exact form prints them: a chain of two
    holds no double pendulum's parameters here (``Chain.exact_model`` None), so ``f(params)`` against
    ``f(params.as_chain())`` compares two forms of one model through a whole capability (issue 52: one
    model, the form of its code an argument; by default a chain of two runs as the double pendulum)."""
    from skewpend.symbolic.chain import Chain

    monkeypatch.setattr(Chain, "exact_model", lambda self: None)


# -- the quick selection: `python -m pytest -m "not slow"` ------------------------------------------------
#: Modules whose every test is slow: a browser, a report built per module, the docs' build, and the docs'
#: examples (a page's examples run in reading order, each after the ones above it, so a quick selection
#: of them would run the slow ones anyway).
SLOW_MODULES = {"test_report_browser.py", "test_explorer_browser.py", "test_widget_browser.py", "test_report.py",
                "test_chain_report.py", "test_chain_explorer.py",
                "test_readme.py", "test_docs.py"}


#: Module-scoped fixtures that fit real data (seconds each): every test that needs one is slow.
SLOW_FIXTURES = {"test_identify.py": {"kaheman_fit", "kaheman_linear"}, "test_identify_cli.py": {"fitted"}}


def _measured_slow() -> set:
    """Node ids of tests measured at >= 1 s (tests/slow.txt, with how they were measured)."""
    path = Path(__file__).resolve().parent / "slow.txt"
    lines = [line.split(None, 1) for line in path.read_text(encoding="utf-8").splitlines()
             if line.strip() and not line.startswith("#")]
    return {node.strip() for _, node in lines}


# -- pytest-xdist (`python -m pytest` runs on every core: pyproject's addopts, --dist loadgroup) ----------
#: Modules run whole on one worker, first: they build something expensive once per module (the docs'
#: site, the README's and the report's runs, a browser and its pages), which two workers would each build,
#: and they are the longest, which started last would leave one core idle at the end.  In this order.
FIRST = ("test_docs.py", "test_readme.py", "test_report_browser.py", "test_report.py", "test_explorer_browser.py",
         "test_widget_browser.py")


def _grouped(path: Path) -> bool:
    """Whether a module's tests stay together on one worker: the modules above, and every module
    with a module-scoped fixture (built once per worker that runs any of its tests)."""
    if path.name in FIRST:
        return True
    text = path.read_text(encoding="utf-8")
    return 'scope="module"' in text or "scope='module'" in text


def pytest_sessionstart(session):
    """With workers (pytest-xdist), the reference model's kernels are compiled once, here, before the
    workers start, rather than by two workers at once (a cold cache; a warm one is only loaded)."""
    config = session.config
    if hasattr(config, "workerinput") or not getattr(config.option, "numprocesses", None):
        return
    try:
        from skewpend.config import reference_parameters
        from skewpend.numeric.kernels import kernel_module

        p = reference_parameters()
        for kind in ({}, {"flip": True}, {"chaos": True}):
            kernel_module(p, **kind)
    except Exception:  # a broken build is reported by the tests themselves
        pass


_GROUPED: dict = {}

#: Modules split into one xdist group per value of a module-scoped parametrised fixture, whose
#: groups share nothing (each builds its own browser, server or export): the explorer's served
#: and static pages run on two workers at once rather than one after the other on one.
SPLIT = {"test_explorer_browser.py": "site"}


def pytest_itemcollected(item):
    """The xdist group of a test, set as it is collected: before any ``pytest_collection_modifyitems``
    (xdist's own reads the groups there, and the order of that hook's implementations differs between
    pytest and xdist versions: set in it, the groups were missed under CI's versions)."""
    path = Path(str(item.fspath))
    if path not in _GROUPED:
        _GROUPED[path] = _grouped(path)
    if _GROUPED[path]:
        by = SPLIT.get(path.name)
        params = getattr(getattr(item, "callspec", None), "params", {})
        name = f"{path.stem}-{params[by]}" if by in params else path.stem
        item.add_marker(pytest.mark.xdist_group(name))


def _groups_broken() -> bool:
    """pytest >= 9.2 builds a node's id from a structured id; pytest-xdist <= 3.8 still writes the group
    into the legacy ``item._nodeid``, which no longer takes: --dist loadgroup silently stops grouping
    (pytest-dev/pytest-xdist#1386). True while both hold."""
    if tuple(int(p) for p in pytest.__version__.split(".")[:2] if p.isdigit()) < (9, 2):
        return False
    import inspect

    import xdist.remote

    return "item._nodeid =" in inspect.getsource(xdist.remote)


@pytest.hookimpl(trylast=True)
def pytest_configure(config):
    """Under --dist loadgroup, stop with the reason where the groups would not hold: the modules sharing
    an expensive fixture would otherwise run it on both workers and race on shared files."""
    if (not hasattr(config, "workerinput") and getattr(config.option, "dist", "no") == "loadgroup"
            and getattr(config.option, "numprocesses", None) and _groups_broken()):
        raise pytest.UsageError(
            f"pytest-xdist's --dist loadgroup does not group under pytest {pytest.__version__} "
            "(pytest-dev/pytest-xdist#1386): install the test extra's pytest (<9.2), or run with -n0")
    # FIRST's order must reach the workers: pytest-xdist >= 3.6 reorders loadscope/loadgroup units by their
    # number of tests unless told not to, which sent the docs' build (9 tests, the longest single test)
    # behind every module of more tests: it started 13 minutes into CI's run, its 6 minutes at the end
    if hasattr(config.option, "loadscopereorder"):
        config.option.loadscopereorder = False


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(config, items):
    slow = _measured_slow()
    for item in items:
        path = Path(str(item.fspath))
        if (item.nodeid.split("@")[0] in slow or path.name in SLOW_MODULES
                or SLOW_FIXTURES.get(path.name, set()) & set(getattr(item, "fixturenames", ()))):
            item.add_marker(pytest.mark.slow)
    rank = {name: i for i, name in enumerate(FIRST)}
    items.sort(key=lambda item: rank.get(Path(str(item.fspath)).name, len(FIRST)))  # stable: else as collected


@pytest.hookimpl(tryfirst=True)
def pytest_runtest_setup(item):
    """A test marked ``needs_tool`` (helpers.needs): skipped with its reason -- failed under CI."""
    mark = item.get_closest_marker("needs_tool")
    if mark is not None:
        from helpers import skip_or_fail

        skip_or_fail(mark.args[0])
