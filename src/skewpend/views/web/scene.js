// skewpend's 3D pendulum (three.js): the roof, the rods (two, or a chain's n), the joints, the hinge axes and the tip's
// trail, turnable with the mouse.  Shared by the explorer, the report's live view and the notebook
// widget.  It draws what it is given -- the rod ends and the hinge axes in the model's frame (j
// points down), computed by the generated physics or replayed from a computed trajectory -- and
// holds no physics of its own.
import * as THREE from "three";
import { OrbitControls } from "three/addons/controls/OrbitControls.js";

// model frame (j points down) -> three.js (y up)
export const world = (x, y, z) => new THREE.Vector3(x, -y, z);
const UP = new THREE.Vector3(0, 1, 0);
// the scene's camera, rods and joints are sized for a pendulum of a metre or two (the double pendulum's a + b =
// 1.8 m): a rig reaching less than MIN_REACH [m] (the rotary pendulum's 0.214 m) is drawn magnified to it
// (setReach), any other at its size
export const MIN_REACH = 0.9;

function placeSegment(mesh, from, to) {
  const d = new THREE.Vector3().subVectors(to, from);
  const len = d.length();
  mesh.position.copy(from).addScaledVector(d, 0.5);
  mesh.scale.set(1, Math.max(len, 1e-6), 1);
  if (len > 0) mesh.quaternion.setFromUnitVectors(UP, d.normalize());
}

/** Which way the last link is drawn from its hinge (skewpend.views.drawing.last_link_sign, the same rule): -1 where
 *  its centre of mass lies against its rod's direction (the parameter `ry<n>` of `p`, in `order`, below 0: a model
 *  read from MJCF whose zero is upright, the DeepMind acrobot's lower arm), else +1 (the rod's end, `tips`). */
export function lastRodSign(order, p) {
  const k = order ? order.lastIndexOf(`ry${order.filter((name) => /^ry\d+$/.test(name)).length}`) : -1;
  return k >= 0 && p[k] < 0 ? -1 : 1;
}

/** The scene on `canvas`: {pose(tips, axes, size, hinges, sign), setReach(reach), frame(centre, radius), toModel(v), pushTrail(), clearTrail(),
 *  render(), resize(), geometry, camera, controls, renderer, rods: {rod1, rod2, joint1, bob, all}}.  `trail`:
 *  points kept.  Any number of rods (a chain of links): the pose's arrays say how many. */
export function createScene(canvas, { trail = 1200, background = 0x0f1722 } = {}) {
  const renderer = new THREE.WebGLRenderer({ canvas, antialias: true, preserveDrawingBuffer: true });
  renderer.setPixelRatio(Math.min(window.devicePixelRatio || 1, 2));
  const scene = new THREE.Scene();
  scene.background = new THREE.Color(background);
  const camera = new THREE.PerspectiveCamera(40, 1, 0.01, 100);
  camera.position.set(2.6, 0.4, 4.2);
  const controls = new OrbitControls(camera, canvas);
  controls.target.set(0, -0.9, 0);
  controls.enableDamping = true;
  scene.add(new THREE.HemisphereLight(0xdde8ff, 0x202833, 1.6));
  const sun = new THREE.DirectionalLight(0xffffff, 1.6);
  sun.position.set(3, 5, 4);
  scene.add(sun);
  const grid = new THREE.GridHelper(6, 12, 0x3a4a60, 0x26344a);
  grid.position.y = -3.2;
  scene.add(grid);
  const roof = new THREE.Mesh(new THREE.BoxGeometry(0.9, 0.05, 0.5), new THREE.MeshStandardMaterial({ color: 0x8a96a8 }));
  roof.position.y = 0.06;
  scene.add(roof);

  // the rods, the joints between them, the bob and the hinge axes: the double pendulum's two (rod1, rod2, joint1,
  // axis1, axis2), more as a chain's pose asks for them (rod3, joint2, axis3, ...)
  const ROD_COLORS = [0x4f8fe8, 0xe8864f, 0x59c08f, 0xb78be0, 0xe0c35a, 0x5ec8d8, 0xe06a8c, 0x9aa7b8];
  const AXIS_COLORS = [[0x7ee787, 0x1d4d22], [0xf2cc60, 0x4d3d10], [0x79c0ff, 0x12365a], [0xff9bce, 0x5a1436]];
  const unitRod = new THREE.CylinderGeometry(0.025, 0.025, 1, 20);
  const unitAxis = new THREE.CylinderGeometry(0.012, 0.012, 1, 12);
  const jointGeom = new THREE.SphereGeometry(0.045, 20, 14);
  const jointMat = new THREE.MeshStandardMaterial({ color: 0xdfe6ee });
  const rodList = [], jointList = [], axisList = [];
  const rodColor = (k, n) => (k === n - 1 && n > 1 ? ROD_COLORS[1] : k === 0 ? ROD_COLORS[0] : ROD_COLORS[2 + ((k - 1) % 6)]);
  const joint0 = new THREE.Mesh(jointGeom, jointMat);
  const bob = new THREE.Mesh(new THREE.SphereGeometry(0.05, 20, 14), new THREE.MeshStandardMaterial({ color: ROD_COLORS[1], roughness: 0.45 }));
  scene.add(joint0, bob);
  function ensure(n) { // rods, joints and axes for a pose of n links (the double pendulum's 2 made at once)
    while (rodList.length < n) {
      const k = rodList.length;
      const rod = new THREE.Mesh(unitRod, new THREE.MeshStandardMaterial({ color: ROD_COLORS[Math.min(k, 1)], roughness: 0.45 }));
      rod.name = `rod${k + 1}`;
      const [c, glow] = AXIS_COLORS[k % AXIS_COLORS.length];
      const axis = new THREE.Mesh(unitAxis, new THREE.MeshStandardMaterial({ color: c, emissive: glow }));
      axis.name = `axis${k + 1}`;
      rodList.push(rod); axisList.push(axis);
      scene.add(rod, axis);
      if (k > 0) { const j = new THREE.Mesh(jointGeom, jointMat); j.name = `joint${k}`; jointList.push(j); scene.add(j); }
    }
    rodList.forEach((rod, k) => { rod.visible = k < n; rod.material.color.setHex(rodColor(k, n)); });
    axisList.forEach((axis, k) => { axis.visible = k < n; });
    jointList.forEach((j, k) => { j.visible = k < n - 1; });
    bob.material.color.setHex(rodColor(n - 1, n));
  }
  ensure(2);
  const [rod1, rod2] = rodList, [joint1] = jointList;

  const trailGeom = new THREE.BufferGeometry();
  const trailPos = new Float32Array(trail * 3);
  trailGeom.setAttribute("position", new THREE.BufferAttribute(trailPos, 3));
  trailGeom.setDrawRange(0, 0);
  scene.add(new THREE.Line(trailGeom, new THREE.LineBasicMaterial({ color: 0xffb27a, transparent: true, opacity: 0.7 })));
  let trailCount = 0;
  // something changed since the last render (a pose, the trail, the size, the camera): renderIfChanged()
  // draws only then, so a paused view costs nothing (software WebGL drew the same picture 60 times a second)
  let stale = true;
  controls.addEventListener("change", () => { stale = true; });

  let scale = 1; // scene units per model metre (setReach)
  const view = {
    renderer, camera, controls, rods: { rod1, rod2, joint1, bob, all: rodList },
    geometry: null, // the last pose: {o, t1, t2, n1, e, tips, pivots, axes} in three.js coordinates (t2: the tip)
    /** The drawn rig's reach [m] (how far from the roof its links can be: skewpend.views.drawing.drawn_reach): one
     *  under MIN_REACH is drawn magnified to it, the camera brought closer; returns the scale (scene units per
     *  metre).  Set it before the first pose. */
    setReach(reach) {
      scale = reach > 0 && reach < MIN_REACH ? MIN_REACH / reach : 1;
      if (scale > 1) { // the default view brought to the magnified rig (it reaches MIN_REACH, not 1.8 m)
        const r = MIN_REACH / 1.8;
        controls.target.set(0, -0.9 * r, 0);
        camera.position.set(2.6 * r, 0.4 * r, 4.2 * r);
        controls.update();
        stale = true;
      }
      return scale;
    },
    /** Look at `centre` (the model's frame [m]) from far enough to hold a ball of `radius` [m] around it, the default
     *  view's direction (a chain whose hinge 1 is away from the roof: skewpend.views.drawing.drawn_frame). */
    frame(centre, radius) {
      const k = (1.1 * scale * radius) / 1.8, c = world(scale * centre[0], scale * centre[1], scale * centre[2]);
      controls.target.copy(c);
      camera.position.set(c.x + 2.6 * k, c.y + 1.3 * k, c.z + 4.2 * k);
      controls.update();
      stale = true;
    },
    get scale() { return scale; },
    /** a point of the scene (three.js coordinates) back in the model's frame [m], j down: [x, y, z] */
    toModel(v) { return [v.x / scale, -v.y / scale, v.z / scale]; },
    /** Place the pendulum: `tips` = [x1, y1, z1, x2, y2, z2, ...] (the rods' ends), `axes` = [n1, e, ...] (the
     *  hinge axes, one a rod), `hinges` = the hinges' positions (optional: without them each hinge is drawn at the
     *  end of the rod before), all in the model's frame -- the double pendulum's two rods or a chain's n; each
     *  link is drawn from its hinge to the next one, the last to its rod's end (a rotary pendulum's arm to the
     *  pendulum's hinge at its side; `sign` -1: the last link drawn the other way from its hinge, lastRodSign);
     *  `size`: the length scale of the drawn hinge axes [m]. */
    pose(tips, axes, size, hinges, sign = 1) {
      const n = Math.floor(tips.length / 3);
      ensure(n);
      const at = (v, k) => world(scale * v[3 * k], scale * v[3 * k + 1], scale * v[3 * k + 2]);
      const rodEnds = Array.from({ length: n }, (_, k) => at(tips, k));
      const pivots = Array.from({ length: n }, (_, k) => (hinges ? at(hinges, k) : k === 0 ? world(0, 0, 0) : rodEnds[k - 1]));
      if (sign < 0) rodEnds[n - 1] = pivots[n - 1].clone().multiplyScalar(2).sub(rodEnds[n - 1]); // mirrored at its hinge
      const ends = Array.from({ length: n }, (_, k) => (k < n - 1 ? pivots[k + 1] : rodEnds[n - 1]));
      const dirs = Array.from({ length: Math.floor(axes.length / 3) }, (_, k) => world(axes[3 * k], axes[3 * k + 1], axes[3 * k + 2]).normalize());
      const G = { o: pivots[0], t1: ends[0], t2: ends[n - 1], n1: dirs[0], e: dirs[1], tips: ends, pivots, axes: dirs };
      const half = 0.35 * Math.max(scale * size, 0.5);
      joint0.position.copy(G.o);
      for (let k = 0; k < n; k++) {
        const from = pivots[k];
        placeSegment(rodList[k], from, ends[k]);
        if (k > 0) jointList[k - 1].position.copy(from);
        if (dirs[k]) placeSegment(axisList[k], from.clone().addScaledVector(dirs[k], -half), from.clone().addScaledVector(dirs[k], half));
      }
      bob.position.copy(G.t2);
      view.geometry = G;
      stale = true;
      return G;
    },
    /** add the tip's current position to the trail */
    pushTrail() {
      const G = view.geometry;
      if (!G) return;
      if (trailCount < trail) trailCount++;
      trailPos.copyWithin(3, 0, (trail - 1) * 3);
      trailPos[0] = G.t2.x; trailPos[1] = G.t2.y; trailPos[2] = G.t2.z;
      trailGeom.setDrawRange(0, trailCount);
      trailGeom.attributes.position.needsUpdate = true;
      stale = true;
    },
    clearTrail() { trailCount = 0; trailGeom.setDrawRange(0, 0); stale = true; },
    get trailCount() { return trailCount; },
    /** match the drawing buffer to the canvas's displayed size; true if it changed */
    resize() {
      const w = canvas.clientWidth, h = canvas.clientHeight, r = renderer.getPixelRatio();
      if (w > 0 && h > 0 && (canvas.width !== Math.floor(w * r) || canvas.height !== Math.floor(h * r))) {
        renderer.setSize(w, h, false);
        camera.aspect = w / h;
        camera.updateProjectionMatrix();
        stale = true;
        return true;
      }
      return false;
    },
    render() { renderer.render(scene, camera); stale = false; },
    /** render if anything changed since the last render; true if it drew */
    renderIfChanged() {
      if (!stale) return false;
      view.render();
      return true;
    },
    /** free the WebGL context and the controls' listeners (a notebook cell re-run or removed) */
    dispose() {
      controls.dispose();
      scene.traverse((o) => { if (o.geometry) o.geometry.dispose(); if (o.material) o.material.dispose(); });
      renderer.dispose();
      renderer.forceContextLoss();
    },
    /** the page position of a point (three.js coordinates): for pointing at a rod */
    toPage(point) {
      const v = point.clone().project(camera), r = canvas.getBoundingClientRect();
      return { x: r.left + ((v.x + 1) / 2) * r.width, y: r.top + ((1 - v.y) / 2) * r.height };
    },
  };
  return view;
}
