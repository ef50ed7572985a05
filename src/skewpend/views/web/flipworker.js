// skewpend explorer: the flip-map worker (a classic Web Worker script).  The page builds the worker
// from three texts: the generated physics (self.physics: rhs, from the derivation), the DOP853
// tableau (self.DOP853, SciPy's numbers, the same as the compiled integrator's) and this file.
//
// The method is the library's flip kernel (sp_flip in integrators.c), one trajectory at a time:
// DOP853 with Hairer's error norm and step-size rule (safety factor 0.8), Hairer's initial step,
// until t_end or until any angle (phi or psi; a chain's q1 .. qn) reaches pi in magnitude; the crossing is located on the step's 7th-order
// dense output by sampling and bisection (a step that turns around close to pi is searched by
// golden section).  Nothing here is an equation of motion.
"use strict";

const D = self.DOP853, NS = D.NS, NSTAGES = D.NSTAGES, PI = Math.PI;
const SAFETY = 0.8, MIN_FACTOR = 0.2, MAX_FACTOR = 10;
// the non-zero coefficients of each stage row, as (index, value) lists
const ROWS = D.A.map((row, s) => row.slice(0, s).map((a, j) => [j, a]).filter(([, a]) => a !== 0));

function rms(x, scale) {
  let s = 0;
  for (let i = 0; i < x.length; i++) { const v = x[i] / scale[i]; s += v * v; }
  return Math.sqrt(s / x.length);
}
function stage(y, h, K, s) {
  const out = new Array(y.length), row = ROWS[s];
  for (let i = 0; i < y.length; i++) {
    let acc = row[0][1] * K[row[0][0]][i];
    for (let k = 1; k < row.length; k++) acc = acc + row[k][1] * K[row[k][0]][i];
    out[i] = y[i] + h * acc;
  }
  return out;
}
// the 7 coefficients of the interpolant of component c over a step of h from y to ynew
function denseCoefficients(y, ynew, h, K, c) {
  const dy = ynew[c] - y[c], F = [dy, h * K[0][c] - dy, 2 * dy - h * (K[NS][c] + K[0][c])];
  for (let r = 0; r < 4; r++) {
    let acc = 0;
    for (let j = 0; j < NSTAGES; j++) acc += D.D[r][j] * K[j][c];
    F.push(h * acc);
  }
  return F;
}
function denseValue(y0, F, x) {
  let v = 0;
  for (let k = 6; k >= 0; k--) { v += F[k]; v *= (6 - k) % 2 === 0 ? x : 1 - x; }
  return y0 + v;
}
// the first x in (0, 1] with |q(x)| >= pi on one angle's interpolant, or -1
function locate(y0, F, h, crossed) {
  const ns = 16;
  let lo = 0, hi = -1, best = -1, kbest = 1;
  for (let k = 1; k <= ns; k++) {
    const x = k / ns, v = Math.abs(denseValue(y0, F, x));
    if (v >= PI) { hi = x; break; }
    lo = x;
    if (v > best) { best = v; kbest = k; }
  }
  if (hi < 0 && crossed) { lo = (ns - 1) / ns; hi = 1; }
  if (hi < 0) { // touch and return: the largest |q| around the largest sample
    const r = 0.6180339887498949;
    let a = (kbest - 1) / ns, b = Math.min(1, (kbest + 1) / ns);
    let x1 = b - r * (b - a), x2 = a + r * (b - a);
    let v1 = Math.abs(denseValue(y0, F, x1)), v2 = Math.abs(denseValue(y0, F, x2));
    for (let it = 0; it < 80 && (b - a) * h > 1e-14 && v1 < PI && v2 < PI; it++) {
      if (v1 > v2) { b = x2; x2 = x1; v2 = v1; x1 = b - r * (b - a); v1 = Math.abs(denseValue(y0, F, x1)); }
      else { a = x1; x1 = x2; v1 = v2; x2 = a + r * (b - a); v2 = Math.abs(denseValue(y0, F, x2)); }
    }
    if (v1 >= PI) hi = x1;
    else if (v2 >= PI) hi = x2;
    else return -1;
    lo = (kbest - 1) / ns;
    if (lo >= hi) lo = 0;
  }
  for (let it = 0; it < 80 && (hi - lo) * h > 1e-13; it++) {
    const mid = 0.5 * (lo + hi);
    if (Math.abs(denseValue(y0, F, mid)) >= PI) hi = mid; else lo = mid;
  }
  return hi;
}
function nextAfter(t) { // the next double above t >= 0
  const b = new Float64Array([t]), u = new BigUint64Array(b.buffer);
  u[0] += 1n;
  return b[0];
}

// One start at rest from the angles q0 (phi0, psi0; a chain's n): [flip time (NaN: none by t_end), which (the
// angle's index: 0 phi, 1 psi, ...; -1 none, -2 failed), steps]
function flipCell(q0, p, tEnd, rtol, atol, maxSteps) {
  const rhs = self.physics.rhs, nq = q0.length, n = 2 * nq;
  let y = [...q0, ...new Array(nq).fill(0)], f = rhs(y, p), t = 0;
  if (!y.concat(f).every(Number.isFinite)) return [NaN, -2, 0];
  // Hairer's initial step
  const sc = y.map((v) => atol + Math.abs(v) * rtol), d0 = rms(y, sc), d1 = rms(f, sc);
  const ha = Math.min(d0 < 1e-5 || d1 < 1e-5 ? 1e-6 : 0.01 * d0 / d1, tEnd);
  const f1 = rhs(y.map((v, i) => v + ha * f[i]), p), d2 = rms(f1.map((v, i) => v - f[i]), sc) / ha;
  const h1 = !Number.isFinite(d2) ? ha * 1e-3 : (d1 <= 1e-15 && d2 <= 1e-15 ? Math.max(1e-6, ha * 1e-3)
    : Math.pow(0.01 / Math.max(d1, d2), 1 / 8));
  let h = Math.min(100 * ha, h1, tEnd), nacc = 0, nrej = 0, lastRejected = false;
  const K = new Array(NSTAGES);
  for (;;) {
    if (!(h >= 10 * (nextAfter(t) - t)) || nacc + nrej >= maxSteps) return [NaN, -2, nacc + nrej];
    const tnew = Math.min(t + h, tEnd), H = tnew - t;
    K[0] = f;
    for (let s = 1; s < NS; s++) K[s] = rhs(stage(y, H, K, s), p);
    const ynew = stage(y, H, K, NS);
    K[NS] = rhs(ynew, p);
    let e5 = 0, e3 = 0, bad = 0;
    for (let i = 0; i < n; i++) {
      let a5 = 0, a3 = 0;
      for (let j = 0; j <= NS; j++) { a5 += D.E5[j] * K[j][i]; a3 += D.E3[j] * K[j][i]; }
      const r = 1 / (atol + rtol * Math.max(Math.abs(y[i]), Math.abs(ynew[i])));
      const u = a5 * r, v = a3 * r;
      e5 += u * u; e3 += v * v;
      bad += 0 * ynew[i] + 0 * K[NS][i];
    }
    const nonfinite = !Number.isFinite(bad) || !Number.isFinite(e5) || !Number.isFinite(e3);
    let err = Math.abs(H) * e5 / Math.sqrt((e5 + 0.01 * e3) * n);
    if (nonfinite) err = Infinity; else if (e5 === 0 && e3 === 0) err = 0;
    const grow = SAFETY / Math.sqrt(Math.sqrt(Math.sqrt(err)));
    if (!(err < 1)) {
      h = H * (nonfinite ? MIN_FACTOR : Math.max(MIN_FACTOR, grow));
      lastRejected = true; nrej++;
      continue;
    }
    const up = err === 0 ? MAX_FACTOR : Math.min(MAX_FACTOR, grow);
    h = H * (lastRejected ? Math.min(1, up) : up);
    lastRejected = false; nacc++;
    let best = Infinity, who = -1;
    for (let c = 0; c < nq; c++) {
      const a0 = Math.abs(y[c]), a1 = Math.abs(ynew[c]), v0 = y[nq + c], v1 = ynew[nq + c];
      const crossed = a1 >= PI;
      if (!crossed && !(v0 * v1 <= 0 && Math.max(a0, a1) + H * Math.max(Math.abs(v0), Math.abs(v1)) >= PI)) continue;
      for (let s = NS + 1; s < NSTAGES; s++) if (!K[s]) K[s] = rhs(stage(y, H, K, s), p);
      const x = locate(y[c], denseCoefficients(y, ynew, H, K, c), H, crossed);
      if (x >= 0 && t + x * H < best) { best = t + x * H; who = c; }
    }
    if (who >= 0) return [Math.min(best, tnew), who, nacc + nrej];
    for (let s = NS + 1; s < NSTAGES; s++) K[s] = undefined;
    y = ynew; f = K[NS]; t = tnew;
    if (t >= tEnd) return [NaN, -1, nacc + nrej];
  }
}
self.flipCell = flipCell;

// a task: {id, p, cells: [[phi0, psi0], ...] (a chain's: [q1, .., qn]), tEnd, rtol, atol, maxSteps} -> {id, time, which, steps}
self.onmessage = (ev) => {
  const { id, p, cells, tEnd, rtol, atol, maxSteps } = ev.data;
  const time = new Float64Array(cells.length), which = new Int8Array(cells.length);
  let steps = 0;
  cells.forEach((q0, k) => {
    const [ft, w, s] = flipCell(q0, p, tEnd, rtol, atol, maxSteps);
    time[k] = ft; which[k] = w; steps += s;
  });
  self.postMessage({ id, time, which, steps }, [time.buffer, which.buffer]);
};
