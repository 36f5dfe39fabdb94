// The model drawn in the view: one BufferGeometry whose position attribute is overwritten in
// place by every pose (no per-frame allocation), a Mesh for a soup and Points for a cloud.
import * as THREE from 'three';

/**
 * Above this many vertices a soup is flat-shaded (normals from screen-space derivatives), so
 * a pose of millions of vertices costs no normal recomputation.
 */
const kSmoothLimit = 1_000_000;
// THREE.Color keeps linear RGB (hex is read as sRGB): what vertex colours take.
const kBase = new THREE.Color(0xa9b4c2);
const kFold = new THREE.Color(0xff0000);

export class ModelView {
  /**
   * data: api.model()'s result; kind: "soup" | "cloud"; size: the scene's diagonal; origin:
   * /api/scene's origin, which the server's float32 positions are relative to.
   */
  constructor(data, kind, size, origin) {
    this.vertexCount = data.vertexCount;
    this.origin = origin;
    this.geometry = new THREE.BufferGeometry();
    this.positionAttribute = new THREE.BufferAttribute(new Float32Array(data.positions), 3);
    this.positionAttribute.setUsage(THREE.DynamicDrawUsage);
    this.geometry.setAttribute('position', this.positionAttribute);
    this.smooth = kind !== 'cloud' && data.vertexCount <= kSmoothLimit;
    this.normalsDirty = this.smooth;
    if (kind === 'cloud' || data.triangleCount === 0) {
      this.material = new THREE.PointsMaterial({color: kBase.clone(), size: size / 400});
      this.object = new THREE.Points(this.geometry, this.material);
    } else {
      this.geometry.setIndex(new THREE.BufferAttribute(new Uint32Array(data.indices), 1));
      this.material = new THREE.MeshStandardMaterial({
        color: 0xffffff,
        roughness: 0.75,
        metalness: 0.0,
        side: THREE.DoubleSide,
        flatShading: !this.smooth,
      });
      this.object = new THREE.Mesh(this.geometry, this.material);
    }
    this.object.frustumCulled = false;  // positions change every pose: no bounds kept
    // The origin in the object's (double) position: the GPU sees small float32 offsets and a
    // modelView matrix with a small translation, so a far model is not quantised.
    this.object.position.set(...origin);
    this.weightColours = null;  // Float32Array [3n] linear RGB, or null
    this.folds = null;          // Uint8Array [n], or null
    this.colourAttribute = null;
    this.refreshColours();
  }

  /** World positions (Float64Array [3n]): the drawn relative float32 plus the origin. */
  positions() {
    const relative = this.positionAttribute.array;
    const out = new Float64Array(relative.length);
    for (let i = 0; i < relative.length; ++i) out[i] = relative[i] + this.origin[i % 3];
    return out;
  }

  setPositions(values) {
    if (values.length !== this.positionAttribute.array.length) {
      throw new Error(`the server sent ${values.length / 3} positions for a model of ${
          this.vertexCount} vertices`);
    }
    this.positionAttribute.array.set(values);
    this.positionAttribute.needsUpdate = true;
    this.normalsDirty = this.smooth;
  }

  /** Called before each frame: normals are only recomputed for a frame that shows them. */
  beforeRender() {
    if (this.normalsDirty) {
      this.geometry.computeVertexNormals();
      this.normalsDirty = false;
    }
  }

  setWeightColours(colours) {
    this.weightColours = colours;
    this.refreshColours();
  }

  setFolds(folds) {
    this.folds = folds;
    this.refreshColours();
  }

  /** Folds in red over the weights' colours over the plain colour. */
  refreshColours() {
    const plain = !this.weightColours && !this.folds;
    const usesVertexColours = !plain;
    if (usesVertexColours && !this.colourAttribute) {
      this.colourAttribute = new THREE.BufferAttribute(new Float32Array(3 * this.vertexCount), 3);
      this.geometry.setAttribute('color', this.colourAttribute);
    }
    if (this.material.vertexColors !== usesVertexColours) {
      this.material.vertexColors = usesVertexColours;
      this.material.needsUpdate = true;
    }
    if (plain) {
      this.material.color.copy(kBase);
      return;
    }
    this.material.color.set(0xffffff);
    const out = this.colourAttribute.array;
    const w = this.weightColours;
    const f = this.folds;
    for (let i = 0; i < this.vertexCount; ++i) {
      const k = 3 * i;
      if (f && f[i]) {
        out[k] = kFold.r, out[k + 1] = kFold.g, out[k + 2] = kFold.b;
      } else if (w) {
        out[k] = w[k], out[k + 1] = w[k + 1], out[k + 2] = w[k + 2];
      } else {
        out[k] = kBase.r, out[k + 1] = kBase.g, out[k + 2] = kBase.b;
      }
    }
    this.colourAttribute.needsUpdate = true;
  }
}
