// Maps scalar fields to the colours of `compare`'s scale, as served by /api/colormap: the
// page never computes a colour scale of its own, it only looks values up in the server's table.
import * as THREE from 'three';

import * as api from './api.js';

/** Samples of the scale (the more, the closer a value's colour is to compare's own). */
const kSamples = 1024;

/** The range the scale needs for these fields: [min, max] of their finite values, 0 inside. */
export function rangeOf(...fields) {
  let min = 0;
  let max = 0;
  for (const field of fields) {
    if (!field) continue;
    for (let i = 0; i < field.length; ++i) {
      const v = field[i];
      if (v < min)
        min = v;
      else if (v > max)
        max = v;  // NaN fails both tests
    }
  }
  if (min === max) max = min + 1;  // a constant zero field: any non-empty range
  return [min, max];
}

/**
 * A lookup table over [min, max]: `srgb` bytes (for textures) and `linear` floats (for vertex
 * colours, which three.js takes as linear), each (k + 1) × 3 with the outside colour last.
 */
export async function colourTable(min, max) {
  const {colors, outside} = await api.colormap(min, max, kSamples);
  const all = [...colors, outside];
  const scale = Math.max(...all.flat()) > 1 ? 1 / 255 : 1;  // bytes or [0, 1]: both accepted
  const srgb = new Uint8Array(all.length * 3);
  const linear = new Float32Array(all.length * 3);
  const c = new THREE.Color();
  all.forEach((rgb, i) => {
    c.setRGB(rgb[0] * scale, rgb[1] * scale, rgb[2] * scale, THREE.SRGBColorSpace);
    srgb.set(
        [
          Math.round(rgb[0] * scale * 255), Math.round(rgb[1] * scale * 255),
          Math.round(rgb[2] * scale * 255)
        ],
        3 * i);
    linear.set([c.r, c.g, c.b], 3 * i);
  });
  return {min, max, samples: colors.length, srgb, linear};
}

/** The table row of value v (the outside row for NaN and infinities). */
export function rowOf(table, v) {
  if (!Number.isFinite(v)) return table.samples;
  const t = (v - table.min) / (table.max - table.min);
  return Math.min(table.samples - 1, Math.max(0, Math.round(t * (table.samples - 1))));
}
