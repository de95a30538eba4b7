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

  /// Every stored mesh of the session in one request, with each stroke's placement (PMB2):
  /// `[{stroke, participant, placement, glb}]`, `glb` an ArrayBuffer. The browser's cache keeps
  /// the body and revalidates it with its ETag.
  async meshBundle(session) {
    return decodeMeshBundle(await (await this.request(`/v1/sessions/${session}/meshes?placements=true`)).arrayBuffer());
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

/// The mesh bundle of GET /v1/sessions/{session}/meshes (shared/src/protocol/mesh_bundle.rs):
/// "PMB1", a u32 count, then per mesh the stroke and participant ids (16 bytes each), a u32
/// length and the GLB; u32s little-endian. "PMB2" (`?placements=true`) has the stroke's
/// placement after the two ids: 16 f64 little-endian (null in a PMB1 entry: the identity).
export function decodeMeshBundle(buffer) {
  const view = new DataView(buffer);
  const bytes = new Uint8Array(buffer);
  const fail = (why) => {
    throw new Error(`not a mesh bundle: ${why}`);
  };
  const magic = buffer.byteLength >= 8 ? String.fromCharCode(...bytes.subarray(0, 4)) : "";
  if (magic !== "PMB1" && magic !== "PMB2") fail('it does not start with "PMB1" or "PMB2"');
  const placed = magic === "PMB2" ? 128 : 0;
  const count = view.getUint32(4, true);
  const meshes = [];
  let at = 8;
  for (let i = 0; i < count; i++) {
    if (at + 36 + placed > buffer.byteLength) fail(`it ends inside mesh ${i}`);
    const stroke = uuid(bytes, at);
    const participant = uuid(bytes, at + 16);
    // DataView reads the f64s where they are (they are not 8-byte aligned in the body).
    const placement = placed ? Array.from({ length: 16 }, (_, k) => view.getFloat64(at + 32 + 8 * k, true)) : null;
    const length = view.getUint32(at + 32 + placed, true);
    at += 36 + placed;
    if (at + length > buffer.byteLength) fail(`it ends inside mesh ${i}`);
    meshes.push({ stroke, participant, placement, glb: buffer.slice(at, at + length) });
    at += length;
  }
  if (at !== buffer.byteLength) fail(`${buffer.byteLength - at} bytes follow its ${count} meshes`);
  return meshes;
}

function uuid(bytes, at) {
  const hex = Array.from(bytes.subarray(at, at + 16), (b) => b.toString(16).padStart(2, "0")).join("");
  return `${hex.slice(0, 8)}-${hex.slice(8, 12)}-${hex.slice(12, 16)}-${hex.slice(16, 20)}-${hex.slice(20)}`;
}
