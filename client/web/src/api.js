// The page's HTTP calls. Every call that needs the session's token sends it as a bearer header:
// the token is never put in a URL (docs/web.md).

/// POST /v1/sessions: a new session and its token, `{session, token}`.
export async function createSession() {
  const res = await fetch("/v1/sessions", { method: "POST" });
  if (!res.ok) throw new Error(`cannot create a session: HTTP ${res.status}`);
  return res.json();
}

// How many times a call refused by a rate (429) is sent in all.
const RATE_TRIES = 30;

export class Api {
  constructor(token) {
    this.token = token;
  }

  /// `fetch` with the token; a non-2xx answer throws an Error naming the call and the
  /// proxy's message, with the HTTP `status` (no answer at all throws fetch's own error). A
  /// 429 (past a rate: a session's duplicates, one's solid changes) is sent again after its
  /// `Retry-After`, up to `RATE_TRIES` times in all: each such call says what it changes, so
  /// sending it again is safe (a duplicate names its new id).
  async request(path, init = {}) {
    for (let tries = 1; ; tries++) {
      const res = await fetch(path, {
        ...init,
        headers: { ...(init.headers || {}), authorization: `Bearer ${this.token}` },
      });
      if (res.status !== 429 || tries === RATE_TRIES) return this.answer(path, init, res);
      await new Promise((r) => setTimeout(r, 1000 * Number(res.headers.get("retry-after") || 1)));
    }
  }

  /// `res`, or the Error of a non-2xx answer.
  async answer(path, init, res) {
    if (!res.ok) {
      let detail = "";
      try {
        detail = (await res.json()).message;
      } catch {}
      const err = new Error(`${init.method || "GET"} ${path}: HTTP ${res.status} ${detail}`);
      err.status = res.status;
      err.detail = detail; // the proxy's own words
      throw err;
    }
    return res;
  }

  /// One stroke's mesh, a GLB.
  async strokeMesh(stroke) {
    return (await this.request(`/v1/strokes/${stroke}/mesh`)).arrayBuffer();
  }

  /// Every stored mesh of the session in one request (PMB3: each mesh once, every stroke with
  /// its placement and solid): `[{stroke, participant, placement, solid, glb}]`, `glb` an
  /// ArrayBuffer, the same one for the strokes that share a mesh (a duplicate and its source).
  /// The browser's cache keeps the body and revalidates it with its ETag.
  async meshBundle(session) {
    return decodeMeshBundle(await (await this.request(`/v1/sessions/${session}/meshes?layout=PMB3`)).arrayBuffer());
  }

  /// A stroke's current placement (the last of `GET /v1/strokes/{id}/placements`, read a page
  /// at a time: a page holds at most 1,000, and `next` says where the next one begins).
  async placement(stroke) {
    for (let from = 0; ; ) {
      const page = await (await this.request(`/v1/strokes/${stroke}/placements?from=${from}`)).json();
      if (page.next === undefined) return page.placements[page.placements.length - 1].placement.matrix;
      from = page.next;
    }
  }

  /// Duplicates a finished stroke as a new one of ours (`id`) at `placement`; `key` is this
  /// tab's participant key. Resolves to the new stroke's id.
  async duplicate(stroke, id, placement, key) {
    const res = await this.request(`/v1/strokes/${stroke}/duplicate`, {
      method: "POST",
      headers: { "x-penmesh-key": key, "content-type": "application/json" },
      body: JSON.stringify({ stroke: id, placement: { matrix: placement } }),
    });
    return (await res.json()).stroke;
  }

  /// Sets the solid (`{kind, depth}`) of one of our finished strokes; `key` is this tab's
  /// participant key. The proxy builds its new mesh first, so a solid the stroke cannot be (an
  /// open stroke filled) is refused (an Error with `status` 409 and the proxy's words) and
  /// nothing changes; once stored it is told to every page (`peer_solid`, then `peer_mesh`).
  async setSolid(stroke, solid, key) {
    await this.request(`/v1/strokes/${stroke}/solid`, {
      method: "PUT",
      headers: { "x-penmesh-key": key, "content-type": "application/json" },
      body: JSON.stringify(solid),
    });
  }

  /// Asks the proxy to build (and store, and announce) the mesh of one of our strokes; `key` is
  /// this tab's participant key, which proves we drew it.
  async buildMesh(stroke, key) {
    await this.request(`/v1/strokes/${stroke}/mesh/build`, { method: "POST", headers: { "x-penmesh-key": key } });
  }
}

/// The mesh bundle of GET /v1/sessions/{session}/meshes (shared/src/protocol/mesh_bundle.rs),
/// in any of its layouts, as `[{stroke, participant, placement, solid, glb}]`; u32s and f64s
/// little-endian. "PMB1": a u32 count, then per mesh the stroke and participant ids (16 bytes
/// each), a u32 length and the GLB. "PMB2" (`?placements=true`) has the stroke's placement after
/// the two ids: 16 f64 (null in a PMB1 entry: the identity). "PMB3" (`?layout=PMB3`): a u32
/// count of meshes and one of strokes, each mesh once (a u32 length and the GLB), then per
/// stroke its two ids, placement, solid (a kind byte, 0 line, 1 filled, 2 hole, and the depth, an
/// f64, NaN for none) and the u32 index of its mesh; entries sharing a mesh share its `glb`.
/// `solid` is null in PMB1 and PMB2 (not said). Bytes that are not a bundle throw an Error
/// naming where.
export function decodeMeshBundle(buffer) {
  const bytes = new Uint8Array(buffer);
  const magic = buffer.byteLength >= 8 ? String.fromCharCode(...bytes.subarray(0, 4)) : "";
  if (magic === "PMB3") return decodeMeshTable(buffer);
  if (magic !== "PMB1" && magic !== "PMB2") bundleError('it does not start with "PMB1", "PMB2" or "PMB3"');
  const view = new DataView(buffer);
  const placed = magic === "PMB2" ? 128 : 0;
  const count = view.getUint32(4, true);
  const meshes = [];
  let at = 8;
  for (let i = 0; i < count; i++) {
    if (at + 36 + placed > buffer.byteLength) bundleError(`it ends inside mesh ${i}`);
    const stroke = uuid(bytes, at);
    const participant = uuid(bytes, at + 16);
    const placement = placed ? placementAt(view, at + 32) : null;
    const length = view.getUint32(at + 32 + placed, true);
    at += 36 + placed;
    if (at + length > buffer.byteLength) bundleError(`it ends inside mesh ${i}`);
    meshes.push({ stroke, participant, placement, solid: null, glb: buffer.slice(at, at + length) });
    at += length;
  }
  if (at !== buffer.byteLength) bundleError(`${buffer.byteLength - at} bytes follow its ${count} meshes`);
  return meshes;
}

const SOLID_KINDS = ["line", "filled", "hole"];
const BUNDLED_STROKE_BYTES = 16 + 16 + 128 + 9 + 4;

/// The PMB3 layout: the mesh table, then the strokes naming its meshes.
function decodeMeshTable(buffer) {
  const view = new DataView(buffer);
  const bytes = new Uint8Array(buffer);
  if (buffer.byteLength < 12) bundleError(`it ends inside its head (${buffer.byteLength} bytes)`);
  const nMeshes = view.getUint32(4, true);
  const nStrokes = view.getUint32(8, true);
  const meshes = [];
  let at = 12;
  for (let i = 0; i < nMeshes; i++) {
    if (at + 4 > buffer.byteLength) bundleError(`it ends inside mesh ${i}`);
    const length = view.getUint32(at, true);
    at += 4;
    if (at + length > buffer.byteLength) bundleError(`it ends inside mesh ${i}`);
    meshes.push(buffer.slice(at, at + length));
    at += length;
  }
  const strokes = [];
  for (let i = 0; i < nStrokes; i++) {
    if (at + BUNDLED_STROKE_BYTES > buffer.byteLength) bundleError(`it ends inside stroke ${i}`);
    const kind = SOLID_KINDS[bytes[at + 160]];
    if (kind === undefined) bundleError(`stroke ${i}'s solid is of kind ${bytes[at + 160]}: 0 line, 1 filled or 2 hole`);
    const depth = view.getFloat64(at + 161, true);
    const mesh = view.getUint32(at + 169, true);
    if (mesh >= nMeshes) bundleError(`stroke ${i} shows mesh ${mesh}, but it has ${nMeshes}`);
    strokes.push({
      stroke: uuid(bytes, at),
      participant: uuid(bytes, at + 16),
      placement: placementAt(view, at + 32),
      solid: { kind, depth: Number.isNaN(depth) ? null : depth },
      glb: meshes[mesh],
    });
    at += BUNDLED_STROKE_BYTES;
  }
  if (at !== buffer.byteLength) bundleError(`${buffer.byteLength - at} bytes follow its ${nStrokes} strokes`);
  return strokes;
}

/// A placement's 16 f64s at `at`, read where they are (they are not 8-byte aligned in the body).
function placementAt(view, at) {
  return Array.from({ length: 16 }, (_, k) => view.getFloat64(at + 8 * k, true));
}

function bundleError(why) {
  throw new Error(`not a mesh bundle: ${why}`);
}

function uuid(bytes, at) {
  const hex = Array.from(bytes.subarray(at, at + 16), (b) => b.toString(16).padStart(2, "0")).join("");
  return `${hex.slice(0, 8)}-${hex.slice(8, 12)}-${hex.slice(12, 16)}-${hex.slice(16, 20)}-${hex.slice(20)}`;
}
