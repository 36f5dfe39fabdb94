// The control object drawn in the view: one sphere per control (an InstancedMesh, so a
// lattice of thousands of points is one draw call) and the edges between them.
import * as THREE from 'three';

const kColour = new THREE.Color(0xe8e8e8);
const kSelected = new THREE.Color(0xff9a1f);

export class ControlsView {
  /**
   * controls: /api/scene's "controls"; radius: world units; origin: /api/scene's origin, where
   * the group is put so that its float32 buffers hold small offsets (a far cage stays exact).
   */
  constructor(controls, radius, origin) {
    this.origin = origin;
    this.kind = controls.kind;
    this.count = controls.count;
    this.pose = new Float64Array(3 * this.count);
    controls.pose.forEach((p, i) => this.pose.set(p, 3 * i));
    this.edges = controls.edges ?? [];
    this.selection = new Set();
    this.group = new THREE.Group();
    this.group.position.set(...origin);

    const sphere = new THREE.SphereGeometry(radius, 12, 8);
    this.handles =
        new THREE.InstancedMesh(sphere, new THREE.MeshBasicMaterial(), Math.max(1, this.count));
    this.handles.count = this.count;
    this.handles.instanceMatrix.setUsage(THREE.DynamicDrawUsage);
    this.handles.frustumCulled = false;  // the instances move; no bounds to recompute
    for (let i = 0; i < this.count; ++i) this.handles.setColorAt(i, kColour);
    this.group.add(this.handles);

    this.edgePositions = new Float32Array(6 * this.edges.length);
    const edgeGeometry = new THREE.BufferGeometry();
    edgeGeometry.setAttribute(
        'position',
        new THREE.BufferAttribute(this.edgePositions, 3).setUsage(THREE.DynamicDrawUsage));
    this.lines =
        new THREE.LineSegments(edgeGeometry, new THREE.LineBasicMaterial({color: 0x7fb4ff}));
    this.lines.frustumCulled = false;
    this.group.add(this.lines);

    this.matrix = new THREE.Matrix4();
    this.update();
  }

  position(i, out = new THREE.Vector3()) {
    return out.fromArray(this.pose, 3 * i);
  }

  /** Moves every selected control by (dx, dy, dz). */
  moveSelection(dx, dy, dz) {
    for (const i of this.selection) {
      this.pose[3 * i] += dx;
      this.pose[3 * i + 1] += dy;
      this.pose[3 * i + 2] += dz;
    }
    this.update();
  }

  setPose(pose) {
    this.pose.set(pose);
    this.update();
  }

  /** Selects control i (-1: none), or with `add` toggles it in the selection. */
  select(i, add) {
    if (!add) this.selection.clear();
    if (i < 0) {
      // nothing to add
    } else if (add && this.selection.has(i))
      this.selection.delete(i);
    else
      this.selection.add(i);
    for (let j = 0; j < this.count; ++j)
      this.handles.setColorAt(j, this.selection.has(j) ? kSelected : kColour);
    this.handles.instanceColor.needsUpdate = true;
  }

  /** The selection's centroid (world units), or null when nothing is selected. */
  selectionCentre(out = new THREE.Vector3()) {
    if (this.selection.size === 0) return null;
    out.set(0, 0, 0);
    for (const i of this.selection)
      out.x += this.pose[3 * i], out.y += this.pose[3 * i + 1], out.z += this.pose[3 * i + 2];
    return out.multiplyScalar(1 / this.selection.size);
  }

  /** The control under the ray, or -1. */
  pick(raycaster) {
    const hits = raycaster.intersectObject(this.handles, false);
    return hits.length > 0 ? hits[0].instanceId : -1;
  }

  update() {
    const p = this.pose;
    const o = this.origin;
    for (let i = 0; i < this.count; ++i) {
      this.matrix.makeTranslation(p[3 * i] - o[0], p[3 * i + 1] - o[1], p[3 * i + 2] - o[2]);
      this.handles.setMatrixAt(i, this.matrix);
    }
    this.handles.instanceMatrix.needsUpdate = true;
    this.handles.computeBoundingSphere();  // raycasting tests it first
    const e = this.edgePositions;
    this.edges.forEach(([a, b], k) => {
      for (let c = 0; c < 3; ++c) {
        e[6 * k + c] = p[3 * a + c] - o[c];
        e[6 * k + 3 + c] = p[3 * b + c] - o[c];
      }
    });
    this.lines.geometry.attributes.position.needsUpdate = true;
  }
}
