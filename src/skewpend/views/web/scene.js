// skewpend's 3D pendulum (three.js): the roof, both rods, the joints, both hinge axes and the tip's
// trail, turnable with the mouse.  Shared by the explorer, the report's live view and the notebook
// widget.  It draws what it is given -- the rod ends and the hinge axes in the model's frame (j
// points down), computed by the generated physics or replayed from a computed trajectory -- and
// holds no physics of its own.
import * as THREE from "three";
import { OrbitControls } from "three/addons/controls/OrbitControls.js";

// model frame (j points down) -> three.js (y up)
export const world = (x, y, z) => new THREE.Vector3(x, -y, z);
const UP = new THREE.Vector3(0, 1, 0);

function placeSegment(mesh, from, to) {
  const d = new THREE.Vector3().subVectors(to, from);
  const len = d.length();
  mesh.position.copy(from).addScaledVector(d, 0.5);
  mesh.scale.set(1, Math.max(len, 1e-6), 1);
  if (len > 0) mesh.quaternion.setFromUnitVectors(UP, d.normalize());
}

/** The scene on `canvas`: {pose(tips, axes, size), pushTrail(), clearTrail(), render(), resize(),
 *  geometry, camera, controls, renderer, rods: {rod1, rod2, joint1, bob}}.  `trail`: points kept. */
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

  const rodMat1 = new THREE.MeshStandardMaterial({ color: 0x4f8fe8, roughness: 0.45 });
  const rodMat2 = new THREE.MeshStandardMaterial({ color: 0xe8864f, roughness: 0.45 });
  const unitRod = new THREE.CylinderGeometry(0.025, 0.025, 1, 20);
  const rod1 = new THREE.Mesh(unitRod, rodMat1); rod1.name = "rod1";
  const rod2 = new THREE.Mesh(unitRod, rodMat2); rod2.name = "rod2";
  const jointMat = new THREE.MeshStandardMaterial({ color: 0xdfe6ee });
  const joint0 = new THREE.Mesh(new THREE.SphereGeometry(0.045, 20, 14), jointMat);
  const joint1 = new THREE.Mesh(new THREE.SphereGeometry(0.045, 20, 14), jointMat);
  const bob = new THREE.Mesh(new THREE.SphereGeometry(0.05, 20, 14), rodMat2);
  const unitAxis = new THREE.CylinderGeometry(0.012, 0.012, 1, 12);
  const axis1 = new THREE.Mesh(unitAxis, new THREE.MeshStandardMaterial({ color: 0x7ee787, emissive: 0x1d4d22 }));
  const axis2 = new THREE.Mesh(unitAxis, new THREE.MeshStandardMaterial({ color: 0xf2cc60, emissive: 0x4d3d10 }));
  axis1.name = "axis1"; axis2.name = "axis2";
  scene.add(rod1, rod2, joint0, joint1, bob, axis1, axis2);

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

  const view = {
    renderer, camera, controls, rods: { rod1, rod2, joint1, bob },
    geometry: null, // the last pose: {o, t1, t2, n1, e} in three.js coordinates
    /** Place the pendulum: `tips` = [x1, y1, z1, x2, y2, z2] (rod ends), `axes` = [n1, e] (hinge
     *  axes), both in the model's frame; `size`: the length scale of the drawn hinge axes [m]. */
    pose(tips, axes, size) {
      const G = { o: world(0, 0, 0), t1: world(tips[0], tips[1], tips[2]), t2: world(tips[3], tips[4], tips[5]),
                  n1: world(axes[0], axes[1], axes[2]).normalize(), e: world(axes[3], axes[4], axes[5]).normalize() };
      placeSegment(rod1, G.o, G.t1);
      placeSegment(rod2, G.t1, G.t2);
      joint1.position.copy(G.t1);
      bob.position.copy(G.t2);
      const half = 0.35 * Math.max(size, 0.5);
      placeSegment(axis1, G.o.clone().addScaledVector(G.n1, -half), G.o.clone().addScaledVector(G.n1, half));
      placeSegment(axis2, G.t1.clone().addScaledVector(G.e, -half), G.t1.clone().addScaledVector(G.e, half));
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
