// The page of `spacewarp view`: shows the model and its controls, sends each drag's pose to
// the server (one request in flight, the latest pose wins) and draws the positions it returns.
// Frames are drawn on demand, never in a loop. window.spacewarp is the hook the browser tests
// and the latency benchmark drive (see README.md, "The page, its browser tests and its latency").
import * as THREE from 'three';
import {OrbitControls} from 'three/addons/controls/OrbitControls.js';
import {TransformControls} from 'three/addons/controls/TransformControls.js';

import * as api from './api.js';
import {colourTable, rangeOf, rowOf} from './colours.js';
import {ControlsView} from './controls_view.js';
import {ModelView} from './model_view.js';

const $ = (id) => document.getElementById(id);
const statusLine = $('status');
const showStatus = (text) => (statusLine.textContent = text);
const showError = (error) => {
  showStatus(`error: ${error.message ?? error}`);
  console.error(error);
};

// ---- the three.js scene ----------------------------------------------------------------
const container = $('view');
/**
 * Whether WebGL runs on the CPU (SwiftShader, llvmpipe: headless Chromium, no GPU), where
 * multisampling costs more than the rest of a frame: then it is off.
 */
function softwareWebGl() {
  const gl = document.createElement('canvas').getContext('webgl2');
  const info = gl?.getExtension('WEBGL_debug_renderer_info');
  const name = info ? gl.getParameter(info.UNMASKED_RENDERER_WEBGL) : '';
  gl?.getExtension('WEBGL_lose_context')?.loseContext();
  return /swiftshader|llvmpipe|software/i.test(name);
}

// The drawing buffer is read back by screenshot() right after a render, in the same task,
// so it need not be preserved between frames.
const renderer = new THREE.WebGLRenderer({antialias: !softwareWebGl()});
renderer.setPixelRatio(window.devicePixelRatio);
renderer.setClearColor(0x1e1f22);
container.appendChild(renderer.domElement);
const canvas = renderer.domElement;

const scene3 = new THREE.Scene();
const camera = new THREE.PerspectiveCamera(40, 1, 0.01, 100);
scene3.add(new THREE.HemisphereLight(0xffffff, 0x404050, 1.6));
const sun = new THREE.DirectionalLight(0xffffff, 1.6);
scene3.add(camera);
camera.add(sun);  // a headlight: every side the user turns to is lit
sun.position.set(0.4, 0.6, 1);

let model = null;
let controls = null;
let sceneInfo = null;

// ---- drawing on demand ---------------------------------------------------------------
let frameQueued = false;
let appliedSeq = 0;       // the latest pointer move whose pose the drawn positions include
const pendingMoves = [];  // [seq, time] of moves not drawn yet, oldest first
const frameWaiters = [];
const hook = {
  latencies: [],
  frames: 0,
  deformMs: [],  // each pose response's X-Spacewarp-Deform-Ms (an addition to the contract)
};

function render() {
  model?.beforeRender();
  renderer.render(scene3, camera);
}

function drawFrame() {
  frameQueued = false;
  render();
  hook.frames += 1;
  const now = performance.now();
  let done = 0;
  while (done < pendingMoves.length && pendingMoves[done][0] <= appliedSeq) {
    hook.latencies.push(now - pendingMoves[done][1]);
    ++done;
  }
  if (done > 0) pendingMoves.splice(0, done);
  frameWaiters.splice(0).forEach((resolve) => resolve());
}

function requestFrame() {
  if (frameQueued) return;
  frameQueued = true;
  requestAnimationFrame(drawFrame);
}

const nextFrame = () => new Promise((resolve) => (frameWaiters.push(resolve), requestFrame()));

function resize() {
  const {clientWidth: w, clientHeight: h} = container;
  renderer.setSize(w, h, false);
  camera.aspect = w / Math.max(1, h);
  camera.updateProjectionMatrix();
  requestFrame();
}
new ResizeObserver(resize).observe(container);

// ---- the pose: one request in flight, the latest pose wins ----------------------------
let moveSeq = 0;
let inFlight = false;
let poseDirty = false;
let idleWaiters = [];
let foldsOn = false;

async function pump() {
  inFlight = true;
  while (poseDirty) {
    poseDirty = false;
    const seq = moveSeq;
    try {
      // fetch copies the body when called, so the pose may change while this is in flight.
      const {positions, deformMs} = await api.pose(controls.pose);
      model.setPositions(positions);
      hook.deformMs.push(deformMs);
      if (foldsOn) model.setFolds(await api.folds());
      appliedSeq = seq;
      requestFrame();
    } catch (error) {
      showError(error);
      requestFrame();  // the controls where they were moved, the model where it was
    }
  }
  inFlight = false;
  idleWaiters.splice(0).forEach((resolve) => resolve());
}

function sendPose() {
  poseDirty = true;
  if (!inFlight) pump();
}

/** Resolves once every pose sent so far is drawn. */
async function settled() {
  while (inFlight || poseDirty) await new Promise((resolve) => idleWaiters.push(resolve));
  await nextFrame();
}

// No frame here: the moved controls are drawn with the positions of their pose, so that a
// frame of a large model is not drawn twice per move (once for the controls alone).
function controlsMoved(time) {
  moveSeq += 1;
  pendingMoves.push([moveSeq, time]);
  placeGizmo();
  sendPose();
}

// ---- colours: a control's weights on the model and on a slice plane ---------------------
let weightsControl = -1;  // the control whose weights are shown, or -1
let weights = null;       // Float32Array [n] of that control, or null
let slice = null;         // api.slice()'s result, or null
let sliceMesh = null;

async function refreshColours() {
  if (weightsControl >= 0)
    weights = await api.weights(weightsControl);
  else
    weights = null;
  if (slice)
    slice = await api.slice(
        weightsControl >= 0 ? weightsControl : 0, slice.axis, slice.value, slice.resolution);
  const table = weights || slice ? await colourTable(...rangeOf(weights, slice?.values)) : null;
  if (weights) {
    const colours = new Float32Array(3 * weights.length);
    for (let i = 0; i < weights.length; ++i) {
      const r = 3 * rowOf(table, weights[i]);
      colours[3 * i] = table.linear[r], colours[3 * i + 1] = table.linear[r + 1],
                  colours[3 * i + 2] = table.linear[r + 2];
    }
    model.setWeightColours(colours);
  } else {
    model.setWeightColours(null);
  }
  drawSlice(table);
  requestFrame();
}

function drawSlice(table) {
  if (sliceMesh) {
    scene3.remove(sliceMesh);
    sliceMesh.geometry.dispose();
    sliceMesh.material.map.dispose();
    sliceMesh.material.dispose();
    sliceMesh = null;
  }
  if (!slice) return;
  const r = slice.resolution;
  const texels = new Uint8Array(4 * r * r);
  for (let i = 0; i < r * r; ++i) {
    const row = 3 * rowOf(table, slice.values[i]);
    texels.set(table.srgb.subarray(row, row + 3), 4 * i);
    texels[4 * i + 3] = Number.isFinite(slice.values[i]) ? 255 : 90;  // outside: faint
  }
  const texture = new THREE.DataTexture(texels, r, r, THREE.RGBAFormat);
  texture.colorSpace = THREE.SRGBColorSpace;
  texture.magFilter = THREE.NearestFilter;
  texture.needsUpdate = true;
  // Corners relative to the scene's origin, where the mesh is put (float32 exact far away).
  const [u, v] = [slice.u, slice.v];
  const o = slice.origin.map((x, c) => x - sceneInfo.origin[c]);
  const corners = new Float32Array(12);
  for (let c = 0; c < 3; ++c) {
    corners[c] = o[c];
    corners[3 + c] = o[c] + u[c];
    corners[6 + c] = o[c] + u[c] + v[c];
    corners[9 + c] = o[c] + v[c];
  }
  // Texel (i, j) is value i + r·j, at origin + (i + ½)/r·U + (j + ½)/r·V.
  const geometry = new THREE.BufferGeometry();
  geometry.setAttribute('position', new THREE.BufferAttribute(corners, 3));
  geometry.setAttribute(
      'uv', new THREE.BufferAttribute(new Float32Array([0, 0, 1, 0, 1, 1, 0, 1]), 2));
  geometry.setIndex([0, 1, 2, 0, 2, 3]);
  const material =
      new THREE.MeshBasicMaterial({map: texture, side: THREE.DoubleSide, transparent: true});
  sliceMesh = new THREE.Mesh(geometry, material);
  sliceMesh.position.set(...sceneInfo.origin);
  scene3.add(sliceMesh);
}

async function showWeights(control) {
  weightsControl = control === null || control === undefined || control < 0 ? -1 : control;
  $('colouring').value = weightsControl >= 0 ? 'weights' : 'plain';
  try {
    await refreshColours();
  } catch (error) {
    weightsControl = -1;
    weights = null;
    model.setWeightColours(null);
    $('colouring').value = 'plain';
    requestFrame();
    throw error;
  }
  await nextFrame();
}

async function showSlice(axis, value) {
  if (!axis) {
    slice = null;
  } else {
    slice = {axis, value, resolution: 256, values: null};
  }
  $('slice-axis').value = axis ?? '';
  await refreshColours();
  await nextFrame();
}

async function showFolds(on) {
  foldsOn = Boolean(on);
  $('folds').checked = foldsOn;
  await settled();
  model.setFolds(foldsOn ? await api.folds() : null);
  requestFrame();
  await nextFrame();
}

async function setMethod(name) {
  const result = await api.setMethod(name);
  sceneInfo.method = result.method;
  sceneInfo.hasWeights = result.hasWeights;
  $('method').value = result.method;
  showStatus(`${result.method}${
      result.bindMs ? `: bound in ${Number(result.bindMs).toFixed(0)} ms` : ''}`);
  sendPose();  // the kept pose under the new method
  await settled();
  if (weightsControl >= 0 || slice) {
    if (!result.hasWeights) {
      weightsControl = -1;
      slice = null;
    }
    await refreshColours();
  }
  await nextFrame();
  return result;
}

async function setPose(values) {
  if (values.length !== controls.pose.length)
    throw new Error(`setPose: ${values.length} numbers for ${controls.count} controls`);
  controls.setPose(values);
  controlsMoved(performance.now());
  await settled();
}

// ---- interaction: picking and dragging controls, the gizmo, the orbit camera -------------
const raycaster = new THREE.Raycaster();
const pointer = new THREE.Vector2();
const dragPlane = new THREE.Plane();
const dragOffset = new THREE.Vector3();
const dragHit = new THREE.Vector3();
const scratch = new THREE.Vector3();
let dragging = -1;
let pressedOnNothing = null;  // where a press that hit no control was, until released
let transform = null;
const gizmoTarget = new THREE.Object3D();
scene3.add(gizmoTarget);  // TransformControls needs its object in the scene graph
const gizmoLast = new THREE.Vector3();

function rayFrom(event) {
  const rect = canvas.getBoundingClientRect();
  pointer.set(
      ((event.clientX - rect.left) / rect.width) * 2 - 1,
      -((event.clientY - rect.top) / rect.height) * 2 + 1);
  raycaster.setFromCamera(pointer, camera);
}

// Registered before the listeners of OrbitControls and TransformControls: a press on a control
// drags it (even under the gizmo's centre) and reaches neither of them.
canvas.addEventListener('pointerdown', (event) => {
  if (!controls || event.button !== 0) return;
  rayFrom(event);
  const i = controls.pick(raycaster);
  if (i < 0) {
    if (!transform?.axis) pressedOnNothing = {x: event.clientX, y: event.clientY};
    return;
  }
  event.stopImmediatePropagation();
  if (event.shiftKey || !controls.selection.has(i)) controls.select(i, event.shiftKey);
  if (!controls.selection.has(i)) {  // shift-click took it out of the selection
    placeGizmo();
    requestFrame();
    return;
  }
  orbit.enabled = false;
  dragging = i;
  const centre = controls.position(i);
  dragPlane.setFromNormalAndCoplanarPoint(camera.getWorldDirection(scratch), centre);
  if (raycaster.ray.intersectPlane(dragPlane, dragHit))
    dragOffset.subVectors(centre, dragHit);
  else
    dragOffset.set(0, 0, 0);
  canvas.setPointerCapture(event.pointerId);
  placeGizmo();
  requestFrame();
});

canvas.addEventListener('pointermove', (event) => {
  if (dragging < 0) return;
  const time = performance.now();
  rayFrom(event);
  if (!raycaster.ray.intersectPlane(dragPlane, dragHit)) return;
  dragHit.add(dragOffset).sub(controls.position(dragging, scratch));
  if (dragHit.lengthSq() === 0) return;
  controls.moveSelection(dragHit.x, dragHit.y, dragHit.z);
  controlsMoved(time);
});

const endDrag = (event) => {
  if (pressedOnNothing) {
    // A click (not an orbit) on the background clears the selection.
    if (Math.hypot(event.clientX - pressedOnNothing.x, event.clientY - pressedOnNothing.y) < 3) {
      controls.select(-1, false);
      placeGizmo();
      requestFrame();
    }
    pressedOnNothing = null;
  }
  if (dragging < 0) return;
  dragging = -1;
  orbit.enabled = true;
  if (canvas.hasPointerCapture(event.pointerId)) canvas.releasePointerCapture(event.pointerId);
};
canvas.addEventListener('pointerup', endDrag);
canvas.addEventListener('pointercancel', endDrag);

const orbit = new OrbitControls(camera, canvas);
orbit.addEventListener('change', requestFrame);

function placeGizmo() {
  if (!transform) return;
  const centre = controls.selectionCentre(scratch);
  if (!centre || !$('gizmo').checked) {
    transform.detach();
    return;
  }
  if (!transform.dragging) {
    gizmoTarget.position.copy(centre);
    gizmoLast.copy(centre);
  }
  if (transform.object !== gizmoTarget) transform.attach(gizmoTarget);
}

// ---- start-up ------------------------------------------------------------------------
function fitCamera(bounds) {
  const lo = new THREE.Vector3(...bounds[0]);
  const hi = new THREE.Vector3(...bounds[1]);
  const centre = lo.clone().add(hi).multiplyScalar(0.5);
  const radius = Math.max(1e-9, lo.distanceTo(hi) / 2);
  const distance = (radius / Math.sin(THREE.MathUtils.degToRad(camera.fov / 2))) * 1.05;
  camera.position.copy(centre).add(
      new THREE.Vector3(0.55, 0.35, 1).normalize().multiplyScalar(distance));
  camera.near = distance / 100;
  camera.far = distance * 10;
  camera.updateProjectionMatrix();
  orbit.target.copy(centre);
  orbit.update();
  return radius;
}

function sceneBounds(info) {
  const lo = [...info.model.bounds[0]];
  const hi = [...info.model.bounds[1]];
  for (const p of info.controls.rest ?? []) {
    for (let c = 0; c < 3; ++c) (lo[c] = Math.min(lo[c], p[c])), (hi[c] = Math.max(hi[c], p[c]));
  }
  return [lo, hi];
}

async function start() {
  const [info, data] = await Promise.all([api.scene(), api.model()]);
  sceneInfo = info;
  document.title = `spacewarp view: ${info.model.path.split('/').pop()}`;
  const bounds = sceneBounds(info);
  const radius = fitCamera(bounds);
  model = new ModelView(data, info.model.kind, 2 * radius, info.origin);
  scene3.add(model.object);
  if (info.controls.kind !== 'none' && info.controls.count > 0) {
    controls = new ControlsView(info.controls, radius / 60, info.origin);
    scene3.add(controls.group);
    transform = new TransformControls(camera, canvas);
    transform.setSize(0.7);
    scene3.add(transform.getHelper());
    transform.addEventListener('change', requestFrame);
    transform.addEventListener('dragging-changed', (event) => (orbit.enabled = !event.value));
    transform.addEventListener('objectChange', () => {
      const time = performance.now();
      const p = gizmoTarget.position;
      controls.moveSelection(p.x - gizmoLast.x, p.y - gizmoLast.y, p.z - gizmoLast.z);
      gizmoLast.copy(p);
      controlsMoved(time);
    });
  }

  // The server keeps the last pose it was sent; show its positions rather than the rest's.
  model.setPositions(await api.positions());

  const methodMenu = $('method');
  for (const name of info.methods) methodMenu.add(new Option(name, name));
  methodMenu.value = info.method;
  methodMenu.disabled = info.methods.length < 2;
  methodMenu.addEventListener('change', () => setMethod(methodMenu.value).catch(showError));
  $('colouring').addEventListener('change', (event) => {
    const first = controls?.selection.values().next().value ?? 0;
    showWeights(event.target.value === 'weights' ? first : -1).catch(showError);
  });
  $('folds').addEventListener(
      'change', (event) => showFolds(event.target.checked).catch(showError));
  const sliceFromUi = () => {
    const axis = $('slice-axis').value;
    const c = 'xyz'.indexOf(axis);
    const t = Number($('slice-value').value);
    showSlice(axis || null, axis ? bounds[0][c] + t * (bounds[1][c] - bounds[0][c]) : 0)
        .catch(showError);
  };
  $('slice-axis').addEventListener('change', sliceFromUi);
  $('slice-value').addEventListener('change', sliceFromUi);
  $('gizmo').addEventListener('change', () => (placeGizmo(), requestFrame()));
  for (const what of ['pose', 'rig', 'model']) {
    $(`save-${what}`)
        .addEventListener(
            'click',
            () =>
                hook.save(what).then((paths) => showStatus(`saved ${paths.join(', ')}`), showError),
        );
    $(`save-${what}`).disabled = what !== 'model' && !controls;
  }
  $('screenshot')
      .addEventListener(
          'click',
          () =>
              hook.screenshot().then((paths) => showStatus(`saved ${paths.join(', ')}`), showError),
      );
  showStatus(
      `${info.model.vertexCount.toLocaleString()} vertices, ${info.controls.count} ${
          info.controls.kind} controls\n` +
          `saving into ${info.saveDir}`,
  );
  resize();
  await nextFrame();
}

async function screenshot() {
  await settled();
  render();  // read back in the same task as the render: the buffer is still there
  const blob = await new Promise((resolve) => canvas.toBlob(resolve, 'image/png'));
  if (!blob) throw new Error('the canvas gave no PNG');
  return api.screenshot(blob);
}

Object.assign(hook, {
  ready: null,
  positions: () => model.positions(),
  pose: () => (controls ? controls.pose.slice() : new Float64Array(0)),
  controlScreenPosition(i) {
    const p = controls.position(i).project(camera);
    const rect = canvas.getBoundingClientRect();
    return {
      x: rect.left + ((p.x + 1) / 2) * rect.width,
      y: rect.top + ((1 - p.y) / 2) * rect.height
    };
  },
  setMethod,
  showWeights,
  showFolds,
  showSlice,
  save: async (what) => (await settled(), api.save(what)),
  screenshot,
  // Additions beyond the contract, for tests: set the pose directly, wait for drawn positions.
  setPose,
  settled,
});
hook.ready = start();
hook.ready.catch(showError);
window.spacewarp = hook;
