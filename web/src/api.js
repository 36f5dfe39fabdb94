// The server's HTTP API (apps/view/view_server.h): one function per endpoint. Binary
// bodies are little-endian, which every browser this page runs in is.

/** An error response: the server's one-line message and the HTTP status. */
export class ApiError extends Error {
  constructor(status, message) {
    super(message);
    this.status = status;
  }
}

async function check(response) {
  if (response.ok) return response;
  let message = `${response.status} ${response.statusText}`;
  try {
    const body = await response.json();
    if (body && body.error) message = body.error;
  } catch {
    // not JSON: keep the status line
  }
  throw new ApiError(response.status, `${response.url.replace(location.origin, '')}: ${message}`);
}

/** fetch(), with a network failure (the server is gone) said as such. */
async function request(path, options) {
  try {
    return await fetch(path, options);
  } catch (error) {
    if (error instanceof TypeError) {
      throw new ApiError(0, `${path}: the server stopped: restart spacewarp view`);
    }
    throw error;
  }
}

async function getJson(path) {
  return (await check(await request(path))).json();
}

async function getBinary(path) {
  const response = await check(await request(path));
  return {buffer: await response.arrayBuffer(), headers: response.headers};
}

async function postJson(path, body) {
  const response = await request(path, {
    method: 'POST',
    headers: {'Content-Type': 'application/json'},
    body: JSON.stringify(body),
  });
  return (await check(response)).json();
}

export const scene = () => getJson('/api/scene');

/** { vertexCount, triangleCount, positions: Float32Array [3n], indices: Uint32Array [3t] } */
export async function model() {
  const {buffer} = await getBinary('/api/model');
  const header = new Uint32Array(buffer, 0, 2);
  const n = header[0];
  const t = header[1];
  if (buffer.byteLength !== 8 + 12 * n + 12 * t) {
    throw new ApiError(
        0, `/api/model: ${buffer.byteLength} bytes for ${n} vertices and ${t} triangles`);
  }
  return {
    vertexCount: n,
    triangleCount: t,
    positions: new Float32Array(buffer, 8, 3 * n),
    indices: new Uint32Array(buffer, 8 + 12 * n, 3 * t),
  };
}

/** Posts the controls' positions (Float64Array [3m]); → { positions: Float32Array, deformMs }. */
export async function pose(controls) {
  const response = await check(
      await request('/api/pose', {
        method: 'POST',
        headers: {'Content-Type': 'application/octet-stream'},
        body: controls,
      }),
  );
  const buffer = await response.arrayBuffer();
  return {
    positions: new Float32Array(buffer),
    deformMs: Number(response.headers.get('X-Spacewarp-Deform-Ms')),
  };
}

export const setMethod = (method) => postJson('/api/method', {method});

export async function positions() {
  return new Float32Array((await getBinary('/api/positions')).buffer);
}

export async function weights(control) {
  return new Float32Array((await getBinary(`/api/weights?control=${control}`)).buffer);
}

function vector(headers, name) {
  const text = headers.get(name);
  const v = text ? text.trim().split(/\s+/).map(Number) : [];
  if (v.length !== 3 || !v.every(Number.isFinite))
    throw new ApiError(0, `/api/slice: bad header ${name}: ${text}`);
  return v;
}

/** { values: Float32Array [r·r] (u fastest), resolution, origin, u, v } */
export async function slice(control, axis, value, resolution) {
  const {buffer, headers} = await getBinary(
      `/api/slice?control=${control}&axis=${axis}&value=${value}&resolution=${resolution}`,
  );
  return {
    values: new Float32Array(buffer),
    resolution,
    origin: vector(headers, 'X-Spacewarp-Slice-Origin'),
    u: vector(headers, 'X-Spacewarp-Slice-U'),
    v: vector(headers, 'X-Spacewarp-Slice-V'),
  };
}

/** { colors: [[r,g,b] × n], outside: [r,g,b] } of `compare`'s colour scale over [min, max]. */
export const colormap = (min, max, n) => getJson(`/api/colormap?min=${min}&max=${max}&n=${n}`);

export async function folds() {
  return new Uint8Array((await getBinary('/api/folds')).buffer);
}

export const save = async (what) => (await postJson('/api/save', {what})).paths;

export async function screenshot(blob) {
  const response = await request('/api/screenshot', {
    method: 'POST',
    headers: {'Content-Type': 'image/png'},
    body: blob,
  });
  return (await (await check(response)).json()).paths;
}
