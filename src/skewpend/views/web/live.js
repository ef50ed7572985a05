// skewpend's live motion, shared by the explorer page and the notebook widget: the fixed-step RK4 that
// advances the generated equations (`rhs(y, p)` from ./physics.js, the model's own code) between two screen
// frames.  Nothing here is an equation of motion.

/** The fixed RK4 step [s] of the live motion (its energy drift is shown beside it). */
export const DT = 1 / 1000;
/** At most this many steps per screen frame (a slow frame falls behind real time instead). */
export const MAX_STEPS_PER_FRAME = 4000;

/** One classical RK4 step of dy/dt = rhs(y, p). */
export function rk4(rhs, y, p, h) {
  const k1 = rhs(y, p);
  const k2 = rhs(y.map((v, i) => v + 0.5 * h * k1[i]), p);
  const k3 = rhs(y.map((v, i) => v + 0.5 * h * k2[i]), p);
  const k4 = rhs(y.map((v, i) => v + h * k3[i]), p);
  return y.map((v, i) => v + (h / 6) * (k1[i] + 2 * (k2[i] + k3[i]) + k4[i]));
}

/** Advance `y` by `seconds` in equal steps of at most DT: {y, dt (time advanced), ok}.  A state
 *  that becomes non-finite stops the motion at the last finite one (ok = false). */
export function advance(rhs, y, p, seconds) {
  const n = Math.min(Math.ceil(seconds / DT), MAX_STEPS_PER_FRAME);
  const h = seconds / Math.max(n, 1);
  let done = 0;
  for (let i = 0; i < n; i++) {
    const next = rk4(rhs, y, p, h);
    if (!next.every(Number.isFinite)) return { y, dt: done, ok: false };
    y = next;
    done += h;
  }
  return { y, dt: done, ok: true };
}

/** The frame of a replayed motion to show `elapsed` seconds after its start (times `t`, looping). */
export function frameAt(t, elapsed) {
  const n = t.length, duration = t[n - 1] - t[0];
  const period = duration + (n > 1 ? t[1] - t[0] : 0);
  const e = period > 0 ? elapsed % period : 0;
  let lo = 0, hi = n - 1;
  while (lo < hi) { // the last frame whose time has come
    const mid = (lo + hi + 1) >> 1;
    if (t[mid] - t[0] <= e) lo = mid; else hi = mid - 1;
  }
  return lo;
}
