// The gelenk player: plays the run embedded in this page (binary glTF and data, written by
// gelenk's src/viz/player.rs) with three.js. World coordinates are gelenk's (z up); the glTF
// root node turns them into three.js's y-up frame, and the contact overlay hangs under it.
import * as THREE from 'three';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';

const ROOT_NODE = 'world (z up)';
const NORMAL_LENGTH = 0.1; // m, the drawn contact normals
const $ = (id) => document.getElementById(id);
const data = JSON.parse($('gelenk-data').textContent);
const times = data.times;
const duration = times[times.length - 1];

const canvas = $('view');
const renderer = new THREE.WebGLRenderer({ canvas, antialias: true });
renderer.setPixelRatio(window.devicePixelRatio);
const scene = new THREE.Scene();
scene.background = new THREE.Color(0xdde6ee);
scene.add(new THREE.HemisphereLight(0xffffff, 0x80766a, 2.2));
const sun = new THREE.DirectionalLight(0xffffff, 1.8);
sun.position.set(4, 10, 6);
scene.add(sun);
const camera = new THREE.PerspectiveCamera(40, 1, 0.01, 10000);
const controls = new OrbitControls(camera, canvas);
controls.addEventListener('change', () => render());

let world = null;           // the glTF root node: gelenk's world frame
let action = null;          // the run's animation, driven by setTime
let mixer = null;
const bodyNodes = new Map(); // body name -> its node
let time = 0;
let playing = true;
let speed = 1;
let following = true;
let lastCentre = null;
let drawnContacts = 0;
const highlightMaterial = new THREE.MeshBasicMaterial({ color: 0xff00ff, depthTest: false });
let highlighted = [];       // [mesh, material, renderOrder] to restore

function status(text) {
  $('status').textContent = text;
}

// Contact overlay: points and normals, drawn on top of the bodies.
const maxContacts = Math.max(1, ...data.contacts.offsets.slice(1).map((o, k) => o - data.contacts.offsets[k]));
const pointGeometry = new THREE.BufferGeometry();
pointGeometry.setAttribute('position', new THREE.BufferAttribute(new Float32Array(3 * maxContacts), 3));
pointGeometry.setAttribute('color', new THREE.BufferAttribute(new Float32Array(3 * maxContacts), 3));
const lineGeometry = new THREE.BufferGeometry();
lineGeometry.setAttribute('position', new THREE.BufferAttribute(new Float32Array(6 * maxContacts), 3));
lineGeometry.setAttribute('color', new THREE.BufferAttribute(new Float32Array(6 * maxContacts), 3));
const overlay = new THREE.Group();
overlay.visible = false;
for (const object of [
  new THREE.Points(pointGeometry, new THREE.PointsMaterial({ size: 6, sizeAttenuation: false, vertexColors: true, depthTest: false })),
  new THREE.LineSegments(lineGeometry, new THREE.LineBasicMaterial({ vertexColors: true, depthTest: false })),
]) {
  object.frustumCulled = false;
  object.renderOrder = 10;
  overlay.add(object);
}

// The recorded instant at or before t.
function frameAt(t) {
  let lo = 0;
  let hi = times.length - 1;
  while (lo < hi) {
    const mid = (lo + hi + 1) >> 1;
    if (times[mid] <= t + 1e-9) lo = mid;
    else hi = mid - 1;
  }
  return lo;
}

function updateOverlay(k) {
  const c = data.contacts;
  const from = c.offsets[k];
  const n = c.offsets[k + 1] - from;
  const pp = pointGeometry.attributes.position.array;
  const pc = pointGeometry.attributes.color.array;
  const lp = lineGeometry.attributes.position.array;
  const lc = lineGeometry.attributes.color.array;
  for (let i = 0; i < n; i++) {
    const j = from + i;
    // Touching or penetrating: red; a gap within the contact margin: orange.
    const colour = c.distances[j] <= 0 ? [0.9, 0.05, 0.05] : [1.0, 0.55, 0.0];
    for (let a = 0; a < 3; a++) {
      const p = c.points[3 * j + a];
      pp[3 * i + a] = p;
      lp[6 * i + a] = p;
      lp[6 * i + 3 + a] = p + NORMAL_LENGTH * c.normals[3 * j + a];
      pc[3 * i + a] = colour[a];
      lc[6 * i + a] = colour[a];
      lc[6 * i + 3 + a] = colour[a];
    }
  }
  for (const g of [pointGeometry, lineGeometry]) {
    g.attributes.position.needsUpdate = true;
    g.attributes.color.needsUpdate = true;
  }
  pointGeometry.setDrawRange(0, n);
  lineGeometry.setDrawRange(0, 2 * n);
  drawnContacts = overlay.visible ? n : 0;
}

// Centre of the bodies' origins (three.js frame).
function bodiesCentre() {
  const centre = new THREE.Vector3();
  const p = new THREE.Vector3();
  for (const node of bodyNodes.values()) centre.add(node.getWorldPosition(p));
  return bodyNodes.size ? centre.divideScalar(bodyNodes.size) : null;
}

function plot(id, values, scale, unit, k) {
  const c = $(id);
  const g = c.getContext('2d');
  const w = c.width;
  const h = c.height;
  g.clearRect(0, 0, w, h);
  const finite = values.filter(Number.isFinite);
  if (!finite.length) return;
  let lo = Math.min(...finite);
  let hi = Math.max(...finite);
  const pad = Math.max((hi - lo) * 0.08, 1e-12 * Math.max(1, Math.abs(hi)));
  lo -= pad;
  hi += pad;
  const x = (t) => (duration > 0 ? (t / duration) * (w - 2) + 1 : 1);
  const y = (v) => h - 2 - ((v - lo) / (hi - lo)) * (h - 4);
  g.strokeStyle = '#2a5db0';
  g.lineWidth = 1.5;
  g.beginPath();
  values.forEach((v, i) => (i ? g.lineTo(x(times[i]), y(v)) : g.moveTo(x(times[i]), y(v))));
  g.stroke();
  g.strokeStyle = '#c0392b';
  g.beginPath();
  g.moveTo(x(time), 0);
  g.lineTo(x(time), h);
  g.stroke();
  const now = values[k] * scale;
  $(id.replace('-plot', '-now')).textContent = `${Math.abs(now) >= 1e4 ? now.toExponential(3) : now.toFixed(3)} ${unit}`;
}

function setTime(t) {
  time = Math.min(Math.max(Number(t) || 0, 0), duration);
  if (action) {
    action.time = time;
    mixer.update(0);
  }
  if (world) world.updateMatrixWorld(true);
  if (following) {
    const centre = bodiesCentre();
    if (centre && lastCentre) {
      const delta = centre.clone().sub(lastCentre);
      camera.position.add(delta);
      controls.target.add(delta);
    }
    lastCentre = centre;
  }
  const k = frameAt(time);
  updateOverlay(k);
  $('time').value = String(time);
  $('clock').textContent = `${time.toFixed(3)} s`;
  plot('energy-plot', data.energy, 1, 'J', k);
  plot('penetration-plot', data.penetration, 1000, 'mm', k);
}

function render() {
  camera.updateMatrixWorld();
  renderer.render(scene, camera);
}

function resize() {
  const w = window.innerWidth;
  const h = window.innerHeight;
  renderer.setSize(w, h, false);
  camera.aspect = w / Math.max(h, 1);
  camera.updateProjectionMatrix();
  render();
}

// Points the camera, along its current direction, at the bodies as they are now: their bounding
// box fills the fraction `fill` of the view (0.8 by default).
function fit(fill = 0.8) {
  const box = new THREE.Box3();
  for (const node of bodyNodes.values()) box.expandByObject(node);
  if (box.isEmpty()) {
    const c = new THREE.Vector3(data.centre[0], data.centre[2], -data.centre[1]);
    box.setFromCenterAndSize(c, new THREE.Vector3(4, 4, 4));
  }
  const sphere = box.getBoundingSphere(new THREE.Sphere());
  const radius = Math.max(sphere.radius, 0.3);
  const direction = camera.position.clone().sub(controls.target);
  if (direction.lengthSq() === 0) direction.set(0.55, 0.5, 1.0); // front right, above (x, z up, -y)
  direction.normalize();
  const corners = [];
  for (let i = 0; i < 8; i++) {
    corners.push(new THREE.Vector3(i & 1 ? box.max.x : box.min.x, i & 2 ? box.max.y : box.min.y, i & 4 ? box.max.z : box.min.z));
  }
  // The distance that contains the bounding sphere, then changed (never into the sphere) until
  // the box's corners reach `fill` of the view.
  let distance = radius / Math.sin(THREE.MathUtils.degToRad(camera.fov) / 2) / Math.min(1, camera.aspect);
  controls.target.copy(sphere.center);
  for (let pass = 0; pass < 4; pass++) {
    camera.position.copy(sphere.center).addScaledVector(direction, distance);
    camera.near = Math.max(distance / 1000, 0.001);
    camera.far = distance * 1000;
    camera.updateProjectionMatrix();
    camera.lookAt(sphere.center);
    camera.updateMatrixWorld();
    const extent = Math.max(...corners.map((c) => {
      const v = c.clone().project(camera);
      return Math.max(Math.abs(v.x), Math.abs(v.y));
    }));
    distance = Math.max((distance * extent) / fill, radius * 1.05);
  }
  camera.position.copy(sphere.center).addScaledVector(direction, distance);
  camera.near = Math.max(distance / 1000, 0.001);
  camera.far = distance * 1000;
  camera.updateProjectionMatrix();
  controls.update();
  lastCentre = bodiesCentre();
  render();
}

function setPlaying(on) {
  playing = on;
  $('play').textContent = on ? 'pause' : 'play';
}

let last = performance.now();
function tick(now) {
  const dt = Math.min((now - last) / 1000, 0.1);
  last = now;
  if (playing && action) setTime(time + dt * speed >= duration ? 0 : time + dt * speed);
  render();
  requestAnimationFrame(tick);
}

function bytes(base64) {
  const text = atob(base64.trim());
  const out = new Uint8Array(text.length);
  for (let i = 0; i < text.length; i++) out[i] = text.charCodeAt(i);
  return out.buffer;
}

const ready = new Promise((resolve, reject) => {
  new GLTFLoader().parse(bytes($('gelenk-glb').textContent), '', (gltf) => {
    const parser = gltf.parser;
    const wanted = new Set(data.bodies);
    gltf.scene.traverse((object) => {
      const a = parser.associations.get(object);
      if (!a || a.nodes === undefined) return;
      const name = parser.json.nodes[a.nodes].name;
      if (name === ROOT_NODE) world = object;
      else if (wanted.has(name)) bodyNodes.set(name, object);
    });
    if (!world) {
      reject(new Error(`the glTF has no node "${ROOT_NODE}"`));
      return;
    }
    world.add(overlay);
    scene.add(gltf.scene);
    if (gltf.animations.length) {
      mixer = new THREE.AnimationMixer(gltf.scene);
      action = mixer.clipAction(gltf.animations[0]);
      action.setLoop(THREE.LoopOnce, 1);
      action.clampWhenFinished = true;
      action.play();
      action.paused = true; // time is set, not advanced, by the mixer
    }
    resolve();
  }, reject);
});

$('title').textContent = `${data.scene} · ${duration.toFixed(2)} s, ${data.bodies.length} bodies`;
$('time').max = String(duration);
$('time').addEventListener('input', (e) => { setPlaying(false); setTime(e.target.value); render(); });
$('play').addEventListener('click', () => setPlaying(!playing));
$('speed').addEventListener('change', (e) => { speed = Number(e.target.value); });
$('contacts').addEventListener('change', (e) => { overlay.visible = e.target.checked; setTime(time); render(); });
$('follow').addEventListener('change', (e) => { following = e.target.checked; lastCentre = bodiesCentre(); });
window.addEventListener('keydown', (e) => {
  if (e.code === 'Space' && e.target.tagName !== 'INPUT' && e.target.tagName !== 'SELECT') {
    e.preventDefault();
    setPlaying(!playing);
  }
});
window.addEventListener('resize', resize);

window.gelenkPlayer = {
  ready,
  bodies: data.bodies,
  times,
  duration,
  seek(t) { setTime(t); render(); return time; },
  play() { setPlaying(true); },
  pause() { setPlaying(false); },
  setSpeed(s) { speed = Number(s); $('speed').value = String(s); },
  showContacts(on) { $('contacts').checked = !!on; overlay.visible = !!on; setTime(time); render(); },
  follow(on) { following = !!on; $('follow').checked = following; lastCentre = bodiesCentre(); },
  fit,
  project(x, y, z) {
    const v = new THREE.Vector3(x, y, z).applyMatrix4(world.matrixWorld).project(camera);
    const r = canvas.getBoundingClientRect();
    return { x: r.left + ((v.x + 1) / 2) * r.width, y: r.top + ((1 - v.y) / 2) * r.height };
  },
  bodyPosition(name) {
    const node = bodyNodes.get(name);
    if (!node) return null;
    const p = world.worldToLocal(node.getWorldPosition(new THREE.Vector3()));
    return [p.x, p.y, p.z];
  },
  highlight(name) {
    for (const [mesh, material, order] of highlighted) {
      mesh.material = material;
      mesh.renderOrder = order;
    }
    highlighted = [];
    const node = name == null ? null : bodyNodes.get(name);
    if (node) {
      node.traverse((o) => {
        if (o.isMesh) {
          highlighted.push([o, o.material, o.renderOrder]);
          o.material = highlightMaterial;
          o.renderOrder = 100;
        }
      });
    }
    render();
    return !!node;
  },
  overlayCount() { return drawnContacts; },
  state() {
    const local = (v) => (world ? world.worldToLocal(v.clone()) : v.clone()).toArray();
    return {
      time, playing, speed, following, contacts: overlay.visible,
      camera: local(camera.position), target: local(controls.target),
      clock: $('clock').textContent, energy: $('energy-now').textContent, penetration: $('penetration-now').textContent,
    };
  },
};

ready.then(() => {
  resize();
  setTime(0);
  fit();
  requestAnimationFrame(tick);
}, (error) => {
  status(`cannot load the run: ${error.message || error}`);
  console.error('gelenk player:', error);
});
