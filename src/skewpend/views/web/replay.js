// skewpend's live replay: a computed motion shown in 3D (scene.js), turnable, in real time.  Each
// <figure class="live-view"> holds a canvas, its controls and the states to replay as JSON
// (<script type="application/json" class="live-data">: frame times t [s], the rod ends `tips`, the
// hinges' positions `hinges` and the hinge axes `axes` at each frame, computed by the library from the
// trajectory, the length scale `size` and the drawn rig's `reach`).  Nothing is integrated here: the frames are the library's.  Used by the
// report (one HTML file, this module inlined) and by anything else that shows a computed run.
import { createScene } from "./scene.js";
import { frameAt } from "./live.js";

function setup(figure) {
  const data = JSON.parse(figure.querySelector("script.live-data").textContent);
  const canvas = figure.querySelector("canvas");
  const n = data.t.length;
  let view;
  try {
    view = createScene(canvas, { trail: Math.min(n, 600) });
  } catch (err) { // no WebGL: the still picture stays, with a note
    figure.classList.add("no-webgl");
    const note = figure.querySelector(".live-note");
    if (note) note.textContent = `This browser cannot draw WebGL (${err.message}); the picture shows the start.`;
    return null;
  }
  figure.classList.add("live");
  if (data.reach) view.setReach(data.reach); // a small rig drawn magnified (scene.js)
  const play = figure.querySelector("button.live-play"), scrub = figure.querySelector("input.live-time");
  const label = figure.querySelector("output.live-clock");
  scrub.max = String(n - 1);
  let frame = -1, running = true, shown = -1, origin = null, renders = 0;
  function pose(k) {
    const next = ((k % n) + n) % n;
    if (next !== frame + 1) view.clearTrail(); // a jump (a new loop, the slider): the trail starts again
    frame = next;
    view.pose(data.tips[frame], data.axes[frame], data.size, data.hinges ? data.hinges[frame] : undefined);
    view.pushTrail();
    scrub.value = String(frame);
    label.textContent = `t = ${data.t[frame].toFixed(2)} s`;
    return view.geometry;
  }
  function setRunning(on) {
    running = on;
    play.textContent = on ? "Pause" : "Play";
    play.setAttribute("aria-pressed", on ? "true" : "false");
    origin = null;
  }
  play.addEventListener("click", () => setRunning(!running));
  scrub.addEventListener("input", () => { setRunning(false); pose(parseInt(scrub.value, 10)); });
  function tick(stamp) {
    requestAnimationFrame(tick);
    view.resize();
    if (running) {
      // real time: the frame whose time has come since the start (or since play was pressed)
      if (origin === null) origin = stamp - 1000 * (data.t[frame] - data.t[0]);
      const k = frameAt(data.t, (stamp - origin) / 1000);
      if (k !== shown) { // every frame since the last one drawn goes into the trail
        if (k > frame) for (let j = frame + 1; j <= k; j++) pose(j); else pose(k);
        shown = k;
      }
    }
    view.controls.update(); // the camera's damping: a change marks the view for drawing
    if (view.renderIfChanged()) renders++; // drawn only when something changed: paused, nothing
  }
  pose(0);
  requestAnimationFrame(tick);
  return {
    figure, view, frames: n,
    /** show frame k (paused) and return the drawn links' ends (the next hinges, the tip), their hinges (`pivots`)
     *  and the axes (every rod's: two, or a chain's n), in the model's frame [m] */
    show(k) {
      setRunning(false);
      const G = pose(k);
      view.render();
      const back = (v) => [v.x, -v.y, v.z];
      return { frame, tips: G.tips.flatMap(view.toModel), pivots: G.pivots.flatMap(view.toModel), axes: G.axes.flatMap(back) };
    },
    state: () => ({ frame, running, renders, t: data.t[frame] }),
    play: () => setRunning(true),
  };
}

const views = [...document.querySelectorAll("figure.live-view")].map(setup).filter(Boolean);
window.skewpendReplay = { views };
