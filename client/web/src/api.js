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
  /// proxy's message.
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
      throw new Error(`${init.method || "GET"} ${path}: HTTP ${res.status} ${detail}`);
    }
    return res;
  }

  /// One stroke's mesh, a GLB.
  async strokeMesh(stroke) {
    return (await this.request(`/v1/strokes/${stroke}/mesh`)).arrayBuffer();
  }

  /// Asks the proxy to build (and store, and announce) the mesh of one of our strokes; `key` is
  /// this tab's participant key, which proves we drew it.
  async buildMesh(stroke, key) {
    await this.request(`/v1/strokes/${stroke}/mesh/build`, { method: "POST", headers: { "x-penmesh-key": key } });
  }
}
