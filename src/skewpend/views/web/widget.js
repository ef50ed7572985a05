// skewpend's notebook widget (anywidget's front end): the live 3D pendulum with its sliders in a
// notebook cell.  The model's state, synced with Python (skewpend.views.widget.PendulumWidget):
//   values  {a, b, m1, m2, alpha, g, c1, c2, tau1, tau2}  SI units, alpha in radians
//   y0      [phi, psi, dphi, dpsi]                          the start of the live motion [rad, rad/s]
//   running bool                                            playing or paused
//   run     {} or {t, tips, hinges, axes, y, size, reach, label}  a computed run to replay (Python's simulate)
//   sliders [names]                                         the sliders to show
//   specs   [[key, label, min, max, step, default, unit, degrees]]  the sliders (skewpend.views.frontend.page_sliders:
//           the parameters a slider sets alone, then each joint's start)
//   size    0 or the length scale of the drawn axes [m]     a chain's longest link (else from a, b)
//   reach   0 or the drawn chain's reach [m]                 a rig under scene.js's MIN_REACH is drawn magnified
// A chain of links: its physics (the recursive algorithms' module) takes the full parameter vector;
// `values` holds what its sliders change (g, each joint's damping), the rest comes from physics.P;
// its start is y0 = [q1 .. qn, dq1 .. dqn], the sliders "q<k>_0" the angles.
//   height  the view's height [px]
//   state   {t, y, mode, frame, ok, message}                written here: what is shown now
// A slider moved here changes `values` or `y0` (and drops a replay of other parameters); Python's
// changes arrive as change events.  Every change goes through the model, so two views of one widget
// stay alike.  The live motion is the generated physics (./physics.js) advanced by RK4 (./live.js);
// a replay shows the library's states frame by frame.  No element ids: many widgets share a page.
import { createScene, lastRodSign } from "./scene.js";
import * as physics from "./physics.js";
import { advance, frameAt } from "./live.js";

const DEG = Math.PI / 180;
const ORDER = physics.PARAMETER_ORDER;
const REPORT_MS = 250; // how often the shown state is written back while it moves
const DISSIPATIVE = /^(c|cf|tau)\d+$/; // damping, Coulomb friction, torques: the energy is not conserved

function element(tag, props = {}, ...children) {
  const node = Object.assign(document.createElement(tag), props);
  node.append(...children);
  return node;
}
function fmt(v, digits = 2) { return Number.isFinite(v) ? v.toFixed(digits) : String(v); }

export function render({ model, el }) {
  const root = element("div", { className: "skewpend-widget" });
  const canvas = element("canvas", { className: "sw-canvas" });
  canvas.setAttribute("aria-label", "the pendulum in 3D: drag to turn the view, scroll to zoom");
  const hud = element("div", { className: "sw-hud" });
  const stage = element("div", { className: "sw-stage" }, canvas, hud);
  const play = element("button", { type: "button", className: "sw-play", textContent: "Pause" });
  const restartButton = element("button", { type: "button", className: "sw-restart", textContent: "Restart" });
  const liveButton = element("button", { type: "button", className: "sw-live", textContent: "Live motion", hidden: true });
  const scrub = element("input", { type: "range", className: "sw-scrub", min: 0, max: 0, step: 1, value: 0, hidden: true });
  scrub.setAttribute("aria-label", "frame of the computed run");
  const mode = element("span", { className: "sw-mode" });
  const bar = element("div", { className: "sw-bar" }, play, restartButton, liveButton, scrub, mode);
  const note = element("p", { className: "sw-note", hidden: true });
  const sliderBox = element("div", { className: "sw-sliders" });
  root.append(stage, bar, note, sliderBox);
  el.append(root);

  let view;
  try {
    view = createScene(canvas, { trail: 1200 });
    view.setReach(+model.get("reach") || 0); // a small rig drawn magnified (scene.js)
    const frame = model.get("frame");
    if (frame && frame.length === 2) view.frame(frame[0], frame[1]); // hinge 1 off the roof: its ball in view
  } catch (err) { // no WebGL here: say so, keep the sliders' state readable from Python
    note.textContent = `This browser cannot draw WebGL (${err.message}).`;
    note.hidden = false;
    return () => root.remove();
  }

  // ---- state ------------------------------------------------------------------------------------
  let values = {}, p = [], y = [0, 0, 0, 0], y0 = [0, 0, 0, 0], t = 0, E0 = 0, ok = true, message = "";
  let running = true, run = null, frame = 0, origin = null, lastStamp = 0, lastReport = -Infinity, visible = true;
  let raf = 0;

  // a value not among `values` (a chain's bodies and axes) is the generated module's own
  function vector(v) { return ORDER.map((k, i) => (Number.isFinite(v[k]) ? v[k] : physics.P ? physics.P[i] : 0)); }
  function size() { return +model.get("size") || Math.max(values.a || 1, values.b || 1); }
  function specs() { return model.get("specs") || []; }
  // the index in y0 of a start slider (the last N: "phi0", "psi0"; a chain's "q<k>_0"), or -1
  function startIndex(key) { return specs().slice(-physics.N).map((s) => s[0]).indexOf(key); }
  function isAngle(key) { return !!(specs().find((s) => s[0] === key) || [])[7]; }
  function showMessage(text) { message = text; note.textContent = text; note.hidden = !text; }

  // ---- the sliders ----------------------------------------------------------------------------------
  const inputs = {};
  function shown(key) { // a slider's value as shown (degrees for angles)
    const k = startIndex(key);
    if (k >= 0) return y0[k] / DEG;
    return isAngle(key) ? values[key] / DEG : values[key];
  }
  function buildSliders() {
    sliderBox.replaceChildren();
    const all = specs();
    for (const key of model.get("sliders") || all.map((s) => s[0])) { // Python's choice and order
      const spec = all.find((s) => s[0] === key);
      if (!spec) continue;
      const [, label, min, max, step, , unit] = spec;
      const input = element("input", { type: "range", min, max, step });
      input.dataset.key = key;
      const out = element("output");
      const row = element("label", { className: "sw-slider" }, element("span", { textContent: label }), input, out);
      inputs[key] = { input, out, unit, step, min, max };
      input.addEventListener("input", () => moved(key, parseFloat(input.value)));
      sliderBox.append(row);
    }
    showSliders();
  }
  function showSliders() {
    for (const [key, s] of Object.entries(inputs)) {
      const v = shown(key);
      if (!Number.isFinite(v)) continue;
      // a value from Python outside the slider's range widens it (the physics uses the value as given)
      if (v < +s.input.min) s.input.min = String(v);
      if (v > +s.input.max) s.input.max = String(v);
      if (document.activeElement !== s.input) s.input.value = String(v);
      s.out.textContent = `${fmt(v, s.step < 0.1 ? 2 : 1)} ${s.unit}`;
    }
  }
  function moved(key, v) { // the user moved a slider: the model changes, its events do the rest
    const k = startIndex(key);
    if (k >= 0) {
      const next = y0.slice();
      next[k] = v * DEG;
      model.set("y0", next);
    } else {
      model.set("values", { ...values, [key]: isAngle(key) ? v * DEG : v });
    }
    if (run) model.set("replay", {}); // a computed run of other parameters is not replayed any more
    model.save_changes();
  }

  // ---- the motion -----------------------------------------------------------------------------------
  function pose() {
    const G = view.pose(physics.tips(y, p), physics.axes(y, p), size(), physics.hinges ? physics.hinges(y, p) : undefined,
                        lastRodSign(ORDER, p));
    return G;
  }
  function restart() {
    y = y0.slice();
    t = 0;
    ok = true;
    showMessage("");
    E0 = physics.energy(y, p);
    view.clearTrail();
    pose();
    view.pushTrail();
    report(true);
  }
  function showFrame(k) { // a replayed run's frame k
    frame = Math.max(0, Math.min(run.t.length - 1, k));
    t = run.t[frame];
    y = run.y[frame].slice();
    view.pose(run.tips[frame], run.axes[frame], run.size, run.hinges ? run.hinges[frame] : undefined);
    view.pushTrail();
    scrub.value = String(frame);
  }
  function setRunning(on) {
    running = on;
    play.textContent = on ? "Pause" : "Play";
    play.setAttribute("aria-pressed", on ? "true" : "false");
    origin = null;
    lastStamp = 0;
    report(true);
  }
  function report(force) { // the shown state, written back to Python (throttled while it moves)
    const now = performance.now();
    if (!force && now - lastReport < REPORT_MS) return;
    lastReport = now;
    model.set("shown", { t, y: y.slice(), mode: run ? "replay" : "live", frame: run ? frame : null, ok, message });
    model.save_changes();
  }
  function showHud() {
    if (run) {
      hud.textContent = `t = ${fmt(t)} s`;
      mode.textContent = `replaying ${run.label || "a computed run"} · frame ${frame + 1} of ${run.t.length}`;
      return;
    }
    const E = physics.energy(y, p);
    const damped = Object.entries(values).some(([k, v]) => DISSIPATIVE.test(k) && v !== 0);
    hud.textContent = `t = ${fmt(t)} s · E = ${E.toFixed(4)} J` + (damped ? "" : ` · drift ${(E - E0).toExponential(1)} J`);
    mode.textContent = "live: the generated equations, RK4";
  }

  // ---- the model's changes (from Python, or from this or another view) -------------------------------
  function onValues() {
    values = { ...model.get("values") };
    p = vector(values);
    if (!run) E0 = physics.energy(y, p);
    showSliders();
    if (!run) pose();
  }
  function onY0() {
    y0 = model.get("y0").slice();
    showSliders();
    if (!run) restart();
  }
  function onRun() {
    const r = model.get("replay");
    const next = r && Array.isArray(r.t) && r.t.length ? r : null;
    run = next;
    liveButton.hidden = !run;
    scrub.hidden = !run;
    restartButton.hidden = !!run;
    view.clearTrail();
    if (run) {
      scrub.max = String(run.t.length - 1);
      origin = null;
      showMessage(run.message || "");
      showFrame(0);
      report(true);
    } else {
      restart();
    }
  }
  function onRunning() { if (model.get("running") !== running) setRunning(model.get("running")); }
  function onHeight() { canvas.style.height = `${Math.max(160, +model.get("height") || 420)}px`; }
  function onSliders() { buildSliders(); }
  function onCustom(msg) {
    if (msg && msg.cmd === "restart") {
      if (run) { view.clearTrail(); showFrame(0); origin = null; report(true); } else restart();
    }
  }
  const handlers = { "change:values": onValues, "change:y0": onY0, "change:replay": onRun, "change:running": onRunning,
                     "change:height": onHeight, "change:sliders": onSliders, "msg:custom": onCustom };
  for (const [event, fn] of Object.entries(handlers)) model.on(event, fn);

  play.addEventListener("click", () => { model.set("running", !running); model.save_changes(); });
  restartButton.addEventListener("click", () => onCustom({ cmd: "restart" }));
  liveButton.addEventListener("click", () => { model.set("replay", {}); model.save_changes(); });
  scrub.addEventListener("input", () => {
    if (!run) return;
    if (running) { model.set("running", false); model.save_changes(); }
    view.clearTrail();
    showFrame(parseInt(scrub.value, 10));
    report(true);
  });

  // ---- the animation ----------------------------------------------------------------------------------
  function tick(stamp) {
    raf = requestAnimationFrame(tick);
    if (!visible) { lastStamp = 0; return; }
    view.resize();
    if (running && run) {
      if (origin === null) origin = stamp - 1000 * (run.t[frame] - run.t[0]);
      const k = frameAt(run.t, (stamp - origin) / 1000);
      if (k !== frame) {
        if (k > frame) for (let j = frame + 1; j <= k; j++) showFrame(j);
        else { view.clearTrail(); showFrame(k); }
      }
      report(false);
    } else if (running && ok) {
      const dt = lastStamp ? Math.min((stamp - lastStamp) / 1000, 0.05) : 0;
      lastStamp = stamp;
      if (dt > 0) {
        const step = advance(physics.rhs, y, p, dt);
        y = step.y;
        t += step.dt;
        pose();
        view.pushTrail();
        if (!step.ok) {
          ok = false;
          showMessage(`The motion became non-finite after t = ${fmt(t)} s: change the parameters or restart.`);
          model.set("running", false); // paused for Python too (its change event pauses this view)
          model.save_changes();
          setRunning(false);
        }
        report(false);
      }
    }
    view.controls.update(); // the camera's damping: a change marks the view for drawing
    view.renderIfChanged(); // drawn only when something changed: paused, nothing
    showHud();
  }

  const seen = typeof IntersectionObserver === "function"
    ? new IntersectionObserver((entries) => { visible = entries.some((e) => e.isIntersecting); }) : null;
  if (seen) seen.observe(root);

  values = { ...model.get("values") };
  p = vector(values);
  y0 = model.get("y0").slice();
  running = !!model.get("running");
  play.textContent = running ? "Pause" : "Play";
  onHeight();
  buildSliders();
  onRun();
  raf = requestAnimationFrame(tick);

  // for tests and the curious (per view): what is shown, and where a rod is on the page
  root.skewpend = {
    state: () => ({ t, y: y.slice(), p: p.slice(), running, mode: run ? "replay" : "live", frame, ok, E0,
                    trail: view.trailCount, geometry: view.geometry }),
    view,
  };

  return () => { // the cell is cleared or re-run: stop drawing and free the WebGL context
    cancelAnimationFrame(raf);
    if (seen) seen.disconnect();
    for (const [event, fn] of Object.entries(handlers)) model.off(event, fn);
    view.dispose();
    root.remove();
  };
}

export default { render };
