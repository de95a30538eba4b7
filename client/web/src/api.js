// The page's HTTP calls. Every call that needs the session's token sends it as a bearer header:
// the token is never put in a URL (docs/web.md).

/// POST /v1/sessions: a new session and its token, `{session, token}`.
export async function createSession() {
  const res = await fetch("/v1/sessions", { method: "POST" });
  if (!res.ok) throw new Error(`cannot create a session: HTTP ${res.status}`);
  return res.json();
}

export class Api {
  constructor(token) {
    this.token = token;
  }

  /// `fetch` with the token; a non-2xx answer throws an Error naming the call and the
  /// proxy's message, with the HTTP `status` (no answer at all throws fetch's own error).
  async request(path, init = {}) {
    const res = await fetch(path, {
      ...init,
      headers: { ...(init.headers || {}), authorization: `Bearer ${this.token}` },
    });
    if (!res.ok) {
      let detail = "";
      try {
        detail = (await res.json()).message;
      } catch {}
      const err = new Error(`${init.method || "GET"} ${path}: HTTP ${res.status} ${detail}`);
      err.status = res.status;
      throw err;
    }
    return res;
  }

  /// One stroke's mesh, a GLB.
  async strokeMesh(stroke) {
    return (await this.request(`/v1/strokes/${stroke}/mesh`)).arrayBuffer();
  }

  /// Every stored mesh of the session in one request: `[{stroke, participant, glb}]`, `glb`
  /// an ArrayBuffer. The browser's cache keeps the body and revalidates it with its ETag.
  async meshBundle(session) {
    return decodeMeshBundle(await (await this.request(`/v1/sessions/${session}/meshes`)).arrayBuffer());
  }

  /// Asks the proxy to build (and store, and announce) the mesh of one of our strokes; `key` is
  /// this tab's participant key, which proves we drew it.
  async buildMesh(stroke, key) {
    await this.request(`/v1/strokes/${stroke}/mesh/build`, { method: "POST", headers: { "x-penmesh-key": key } });
  }
}

/// The mesh bundle of GET /v1/sessions/{session}/meshes (shared/src/protocol/mesh_bundle.rs):
/// "PMB1", a u32 count, then per mesh the stroke and participant ids (16 bytes each), a u32
/// length and the GLB; u32s little-endian.
export function decodeMeshBundle(buffer) {
  const view = new DataView(buffer);
  const bytes = new Uint8Array(buffer);
  const fail = (why) => {
    throw new Error(`not a mesh bundle: ${why}`);
  };
  if (buffer.byteLength < 8 || String.fromCharCode(...bytes.subarray(0, 4)) !== "PMB1") fail('it does not start with "PMB1"');
  const count = view.getUint32(4, true);
  const meshes = [];
  let at = 8;
  for (let i = 0; i < count; i++) {
    if (at + 36 > buffer.byteLength) fail(`it ends inside mesh ${i}`);
    const stroke = uuid(bytes, at);
    const participant = uuid(bytes, at + 16);
    const length = view.getUint32(at + 32, true);
    at += 36;
    if (at + length > buffer.byteLength) fail(`it ends inside mesh ${i}`);
    meshes.push({ stroke, participant, glb: buffer.slice(at, at + length) });
    at += length;
  }
  if (at !== buffer.byteLength) fail(`${buffer.byteLength - at} bytes follow its ${count} meshes`);
  return meshes;
}

function uuid(bytes, at) {
  const hex = Array.from(bytes.subarray(at, at + 16), (b) => b.toString(16).padStart(2, "0")).join("");
  return `${hex.slice(0, 8)}-${hex.slice(8, 12)}-${hex.slice(12, 16)}-${hex.slice(16, 20)}-${hex.slice(20)}`;
}
