"""The notebook widget's Python side (``skewpend.widget``): what it syncs, what it refuses, what
it sends, and the front-end module it carries.  The front end itself runs in Chromium in
``tests/test_widget_browser.py``."""

from __future__ import annotations

import json
import re
import subprocess
import sys

import numpy as np
import pytest

pytest.importorskip("anywidget")

import comm  # noqa: E402
from comm.base_comm import BaseComm  # noqa: E402

import skewpend  # noqa: E402
from skewpend import Parameters, ParameterError  # noqa: E402
from skewpend.views import frontend  # noqa: E402
from skewpend.views.widget import FPS, MAX_FRAMES, PendulumWidget, WidgetState  # noqa: E402
from helpers import general_body  # noqa: E402


class RecordingComm(BaseComm):
    def __init__(self, **kwargs):
        self.sent = []
        super().__init__(**kwargs)

    def publish_msg(self, msg_type, data=None, metadata=None, buffers=None, **keys):
        self.sent.append((msg_type, data))


@pytest.fixture(autouse=True)
def recording(monkeypatch):
    monkeypatch.setattr(comm, "create_comm", lambda **kw: RecordingComm(**kw))


def updates(w, key):
    return [d["state"][key] for kind, d in w.comm.sent if kind == "comm_msg" and d.get("method") == "update"
            and key in d["state"]]


def test_the_public_name_and_its_defaults():
    assert "widget" in skewpend.__all__ and "PendulumWidget" in skewpend.__all__
    w = skewpend.widget()
    assert isinstance(w, PendulumWidget)
    assert w.params == skewpend.reference_parameters()
    assert w.y0 == list(skewpend.reference_state())
    assert w.running and w.replay == {} and w.height == 420
    assert w.sliders == ["alpha", "phi0", "psi0", "a", "b", "m1", "m2", "g", "c1", "c2"]
    st = w.state
    assert isinstance(st, WidgetState) and st.mode == "not shown" and st.y.tolist() == w.y0
    # the notebook's first message carries the whole state, the front end's module and style included
    kind, data = w.comm.sent[0]
    assert kind == "comm_open" and data["state"]["_esm"] == w._esm and data["state"]["values"]["alpha"] == 0.6
    assert repr(w).startswith("<PendulumWidget live, running: a=1, b=0.8, m1=1, m2=0.7, alpha=0.6")  # not a call


def test_state_is_synced_to_the_view():
    w = skewpend.widget()
    w.params = w.params.replace(alpha=-0.25, c1=0.1)
    assert updates(w, "values")[-1]["alpha"] == -0.25 and updates(w, "values")[-1]["c1"] == 0.1
    assert w.params.alpha == -0.25 and w.params.c1 == 0.1
    w.y0 = np.array([0.1, 0.2, 0.3, 0.4])
    assert updates(w, "y0")[-1] == [0.1, 0.2, 0.3, 0.4]
    w.pause()
    assert updates(w, "running")[-1] is False
    w.restart()
    assert ("comm_msg", {"method": "custom", "content": {"cmd": "restart"}}) in w.comm.sent


def test_the_view_s_changes_reach_python(caplog):
    w = skewpend.widget()
    # what the front end sends when a slider moves and when it reports what it shows
    values = dict(w.values, alpha=0.5 * np.pi / 180 * 41)
    w.comm.handle_msg({"content": {"data": {"method": "update", "state": {"values": values}}}, "buffers": []})
    assert w.params.alpha == values["alpha"]
    shown = {"t": 1.25, "y": [0.5, -0.25, 1.0, 2.0], "mode": "live", "frame": None, "ok": True, "message": ""}
    w.comm.handle_msg({"content": {"data": {"method": "update", "state": {"shown": shown}}}, "buffers": []})
    st = w.state
    assert (st.t, st.y.tolist(), st.mode, st.frame, st.ok, st.message) == (1.25, shown["y"], "live", None, True, "")
    # a bad value from a view is refused by the same checks as Python's: logged in one line, the
    # trait keeps its value and the view is sent it back
    bad = dict(w.values, m1=-1.0)
    w.comm.sent.clear()
    with caplog.at_level("WARNING"):
        w.comm.handle_msg({"content": {"data": {"method": "update", "state": {"values": bad}}}, "buffers": []})
    assert w.params.m1 == 1.0
    assert updates(w, "values") == [w.values]
    assert any("a change from the view was refused: m1 must be > 0" in r.getMessage() for r in caplog.records)
    # a report that is not one (another program's view) is refused the same way; w.state still reads
    w.comm.handle_msg({"content": {"data": {"method": "update", "state": {"shown": {"t": "soon"}}}}, "buffers": []})
    assert w.state.t == 1.25 and any("a view's report must hold" in r.getMessage() for r in caplog.records)


def test_run_replays_the_library_s_states():
    w = skewpend.widget(y0=(1.5, 0.0, 0.0, 0.0))
    tr = w.run(2.0)
    assert tr.ok and len(tr.t) == 2 * FPS + 1
    np.testing.assert_allclose(np.diff(tr.t), 1 / FPS, rtol=1e-12)
    data = w.replay
    assert data["t"] == tr.t.tolist() and data["y"] == tr.y.tolist()
    assert data["tips"] == tr.tips().tolist() and data["axes"] == tr.axes().tolist()
    assert data["size"] == 1.0 and "taylor" in data["label"] and data["message"] == ""  # simulate's default chose taylor
    ref = skewpend.simulate(w.params, w.y0, 2.0, dt_out=1 / FPS)
    np.testing.assert_array_equal(tr.y, ref.y)  # the same call, the same numbers
    assert "replaying a computed run" in repr(w)
    # a change of parameters or start drops the replay (it was computed for the old ones)
    w.params = w.params.replace(alpha=0.1)
    assert w.replay == {}
    # fixed-step methods: frames on whole steps
    tr = w.run(1.0, method="rk4", dt=0.002)
    assert np.allclose(np.diff(tr.t)[:-1], 0.034) and tr.t[-1] == 1.0 and tr.method == "rk4"
    # a trajectory computed elsewhere is replayed as well; its parameters and start become the widget's
    other = skewpend.simulate(w.params.replace(alpha=0.9), (0.2, 0.1, 0.0, 0.0), 1.0, dt_out=0.05)
    w.show(other)
    assert w.params.alpha == 0.9 and w.y0 == [0.2, 0.1, 0.0, 0.0] and len(w.replay["t"]) == 21


def test_a_run_that_cannot_finish_or_stopped_early_says_so():
    import dataclasses

    from skewpend import Status

    w = skewpend.widget(y0=(3.0, 0.0, 0.0, 0.0))
    with pytest.raises(ParameterError, match="more than max_steps = 40"):  # refused before it starts
        w.run(5.0, max_steps=40)
    assert w.replay == {}
    tr = skewpend.simulate(w.params, w.y0, 1.0, dt_out=1 / FPS)
    stopped = dataclasses.replace(tr, t=tr.t[:10], y=tr.y[:10], energy=tr.energy[:10], work=tr.work[:10],
                                  status=Status.NONFINITE, message="the state became non-finite at t = 0.3 s")
    w.show(stopped)
    assert w.replay["message"] == "The run stopped early: the state became non-finite at t = 0.3 s"
    assert len(w.replay["t"]) == 10


@pytest.mark.parametrize("change, message", [
    (lambda w: setattr(w, "y0", (1.0, 2.0)), "y0 must be 4 numbers"),
    (lambda w: setattr(w, "y0", (1.0, 2.0, float("nan"), 0.0)), "y0 must be finite"),
    (lambda w: setattr(w, "y0", (1e7, 0.0, 0.0, 0.0)), "initial angles must be at most"),
    (lambda w: setattr(w, "y0", "abcd"), "y0 must be 4 numbers"),
    (lambda w: setattr(w, "params", Parameters(a=1, b=1, m1=1, m2=1, g=9.81, axis2=(0, 0, 1))), "bodies and axes are fixed"),
    (lambda w: setattr(w, "params", Parameters()), "numeric"),
    (lambda w: setattr(w, "params", {"alpha": 1.0}), "must be a skewpend.Parameters"),
    (lambda w: setattr(w, "values", {"alpha": 1.0}), "missing a, b, m1"),
    (lambda w: setattr(w, "values", dict(w.values, zeta=1.0)), "unknown zeta"),
    (lambda w: setattr(w, "values", dict(w.values, g=-9.81)), "g must be >= 0"),
    (lambda w: w.run(-1.0), "t_end must be a number of seconds > 0"),
    (lambda w: w.run(float("inf")), "t_end must be a number of seconds > 0"),
    (lambda w: w.run(MAX_FRAMES / FPS + 1), "at most 20000"),
    (lambda w: w.run(1.0, dt_out=0.1), "dt_out cannot be set here"),
    (lambda w: w.run(1.0, out="x.csv"), "out cannot be set here"),
    (lambda w: w.run(1.0, rtol=-1), "rtol"),
    (lambda w: w.run(0.01, method="rk4"), "shorter than one frame"),
    (lambda w: w.run(1.0, method="euler"), "method"),
    (lambda w: w.show("trajectory.csv"), "expected a skewpend.Trajectory"),
    (lambda w: w.show(skewpend.simulate(general_body(), (0.1, 0, 0, 0), 0.1)),  # (kernels other runs compile)
     "bodies and axes differ"),
    (lambda w: w.show(skewpend.simulate(w.params, (0.1, 0, 0, 0), 1.0, keep=False)), "keep=False"),
])
def test_bad_input_is_refused_in_one_line(change, message):
    w = skewpend.widget()
    before = (dict(w.values), list(w.y0), dict(w.replay))
    with pytest.raises(ParameterError, match=message) as info:
        change(w)
    assert "\n" not in str(info.value)
    assert (w.values, w.y0, w.replay) == before  # nothing half changed


@pytest.mark.parametrize("kwargs, message", [
    ({"params": Parameters(a=1.0)}, "numeric"),
    ({"y0": (0, 0, 0)}, "y0 must be 4 numbers"),
    ({"height": 10}, "height must be a whole number from 160"),
    ({"height": 400.5}, "height must be a whole number"),
])
def test_bad_arguments_are_refused(kwargs, message):
    with pytest.raises(ParameterError, match=message):
        skewpend.widget(**kwargs)


def test_general_bodies_get_their_own_physics_and_no_alpha_slider():
    general = Parameters(a=1.0, b=0.8, m1=1.0, m2=0.7, g=9.81, axis2=(0.3, 0.2, 1.0), com2=(0.05, 0.4, 0.0))
    w = skewpend.widget(general)
    assert "alpha" not in w.values and "alpha" not in w.sliders
    assert w.params.axis2 == general.axis2 and w.params.com2 == general.com2
    w.params = general.replace(m2=2.0)
    assert w.params.m2 == 2.0
    from skewpend.numeric.explorer_source import explorer_js
    from skewpend.numeric.conventions import geometry_of

    # the module carries exactly the physics generated for these bodies
    physics = json.dumps(explorer_js(geometry_of(general)), ensure_ascii=False)
    assert physics in w._esm and json.dumps(explorer_js(geometry_of(skewpend.reference_parameters())),
                                            ensure_ascii=False) not in w._esm


def test_the_module_is_self_contained():
    esm = skewpend.widget()._esm
    # registered under name@digest; every import resolves inside the module's own sources
    sources = json.loads(re.search(r"^const sources = (\{.*\});$", esm, re.M).group(1))
    names = set(sources)
    assert {n.split("@")[0] for n in names} == set(frontend.WIDGET_ORDER)
    for name, src in sources.items():
        for spec, dep in src["imports"].items():
            assert dep in names, (name, spec, dep)
            assert f'from "{spec}"' in src["code"] or f"from '{spec}'" in src["code"]
    three = next(s for n, s in sources.items() if n.startswith("three-core@"))
    assert three["code"] == (frontend.WEB_DIR / "vendor" / "three" / "three.core.js").read_text(encoding="utf-8")
    # nothing is fetched: no http(s) URL is imported, and the default export is anywidget's render
    assert not re.search(r"""(import\s*\(|from\s*)["']https?:""", esm)
    assert "export default {" in esm and "async render(context)" in esm
    # the same text for the same bodies: the digests depend on content only
    assert skewpend.widget()._esm == esm


def test_the_module_parses_as_javascript(tmp_path):
    node = __import__("shutil").which("node")
    if node is None:  # pragma: no cover - .ci/run installs Node.js
        pytest.skip("node is needed")
    path = tmp_path / "widget.mjs"
    path.write_text(skewpend.widget()._esm, encoding="utf-8")
    proc = subprocess.run([node, "--check", str(path)], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr


def test_without_anywidget_the_error_says_what_to_install():
    code = ("import sys; sys.modules['anywidget'] = None\n"
            "import skewpend\n"
            "try:\n    skewpend.widget\nexcept ImportError as e:\n    print('ERR', e)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120).stdout
    assert "ERR skewpend.widget needs anywidget: pip install 'skewpend[notebook]'" in out


def test_a_chain_of_links_gets_its_own_widget():
    from skewpend.symbolic.chain import Chain

    chain = Chain.from_lists(3, length=[0.5, 0.4, 0.3], mass=[1.0, 0.8, 0.5], axis=[(0, 0, 1), (0.5, 0, 1), (1, 0, 0)],
                             damping=[0.0, 0.0, 0.01])
    w = skewpend.widget(chain)
    assert w.sliders == ["q1_0", "q2_0", "q3_0", "g", "c1", "c2", "c3"] and len(w.specs) == 7
    assert w.values == {"g": 9.81, "c1": 0.0, "c2": 0.0, "c3": 0.01}
    assert w.y0 == [0.5, 0.5, 0.5, 0.0, 0.0, 0.0] and w.size == 0.5
    assert w.params == chain
    # its physics is the chain's module (printed from the recursive algorithms), not the double pendulum's
    assert "from a chain's recursive algorithms" in w._esm and "export const TERMS = [];" in w._esm
    assert repr(w) == "<PendulumWidget live, running: a chain of 3 links, g=9.81, c3=0.01; y0 = (0.5, 0.5, 0.5, 0, 0, 0)>"
    w.values = {**w.values, "g": 3.7}
    assert w.params.g == 3.7 and w.params.links == chain.links
    # a run replays the library's states of this chain
    tr = w.run(1.0)
    assert tr.params == w.params and np.array(w.replay["tips"]).shape == (len(tr.t), 9)
    assert w.replay["size"] == 0.5
    # refused in one line: a start of the wrong size, a negative damping, another chain, an unknown value
    with pytest.raises(ParameterError, match=r"y0 must be 6 numbers \(q1, q2, q3, dq1, dq2, dq3\)"):
        w.y0 = [0.1, 0.2, 0.0, 0.0]
    with pytest.raises(ParameterError, match="link 2 damping must be >= 0"):
        w.values = {**w.values, "c2": -1.0}
    with pytest.raises(ParameterError, match="chain is fixed when it is made"):
        w.params = chain.replace_link(2, mass=2.0)
    with pytest.raises(ParameterError, match="unknown alpha"):
        w.values = {**w.values, "alpha": 0.3}
    other = skewpend.simulate(chain.replace_link(1, length=0.6), [0.1] * 3 + [0.0] * 3, 0.1, dt_out=0.05)
    with pytest.raises(ParameterError, match="the trajectory's chain differs"):
        w.show(other)
    # what a view reports has the chain's 2 n numbers
    with pytest.raises(ParameterError, match=r"6 numbers"):
        w.shown = {"t": 0.0, "y": [0.0] * 4, "mode": "live"}
