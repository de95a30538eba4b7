// The session's WebSocket (docs/protocol.md): connect (the token as a subprotocol, never in the
// URL), Hello, Points every FLUSH_MS while the pen moves, acks, and the resume of our own strokes
// not yet done after a dropped connection or a reload (every sample of them is kept in
// sessionStorage as it is drawn). Reconnects with backoff.
//
// The page sends every message as a binary frame (codec.js). The proxy answers each connection
// in the form of its latest frame, so a page that sent JSON would receive a move as 277 bytes of
// text (its own set_placement 223): binary, a move costs 147 bytes sent and 164 received, within
// issue 37's 200 bytes on the wire. A watcher only sends a Hello and Pings; they must be binary
// too for it to receive moves in binary. Text frames are read all the same (the proxy's JSON
// error before a Hello, a page switched to JSON with `encoding`): both kinds go to `receive`.
// Protocol 5: a stroke begins on the work plane (`stroke_begin.placement`, kept with the stroke
// for a resume) and `set_placement` places a finished one; `peer_placement` comes to `on`, but
// not the answer to a move of ours while a later move of that stroke is still unanswered: the
// page already shows the later one, and the earlier answer would take the stroke back to where
// it was until the next answer came (a move typed then would start from there).
// Protocol 6: a stroke may begin as a solid (`stroke_begin.solid`, kept likewise); `peer_solid`
// comes to `on`.
//
// Every message from the proxy goes to `on(kind, message)` after this module has taken what it
// needs from it; `retained` only for our own strokes not yet done, `stroke_done` also when a
// resume finds one of them already done.

import { decodeServer, encodeClient } from "./codec.js";

// Samples are sent at most this often while the pen moves (ms); pen-up flushes at once.
const FLUSH_MS = 16;
// A page that only watches sends a Ping after this long without sending anything (ms): the
// proxy closes a connection that sends nothing for --idle-timeout-secs (60 s by default), and
// the page would reconnect and receive the whole history again. The native client's interval.
const KEEPALIVE_MS = 20000;
// Most of our strokes not yet done at once (ended, waiting for `stroke_done`): a pen that comes
// down again while this many wait draws nothing until one is done. Well under the proxy's
// --max-open-strokes (16 by default).
const MAX_UNFINISHED = 8;
// A resume the proxy refused because an old connection of ours still holds the stroke (a
// network gone without a close, until the proxy's heartbeat lets it go) is tried again on this
// connection after this long (ms), as often as it is refused. Each try costs the proxy one
// wait of --claim-wait-ms (2 s by default).
const RETAKE_MS = 2000;
const snap = (value, step) => Math.round(value / step) * step;
// The close code of a token that does not open the session (proxy/src/ws/mod.rs).
const UNAUTHORIZED = 4401;
// How far (CSS px of width, at one unit per px) the mesh's width may stray from the pen's: the
// pressure tolerance the page asks for a stroke is this much width for its brush, or the
// proxy's when that is tighter (docs/web.md, "The mesh and the ink"). The proxy's default
// (0.2 of pressure) is 1.6 px of width with the default brush, 6.4 px with the widest: the
// mesh stepped visibly where the ink tapered.
const WIDTH_TOLERANCE_PX = 0.5;
const MIN_PRESSURE_TOLERANCE = 0.01;

export class Connection {
  /// `grid`: the protocol's quantisation steps [position px, time ms, pressure]. Samples are
  /// snapped to it before they are sent, as the native client does, so what the proxy stores
  /// (it puts every sample on this grid on arrival) is exactly what was sent.
  /// `params`: the proxy's ACUTS defaults [tolerance px, angle degrees, pressure tolerance].
  constructor({ session, token, protocol, grid, params, name, on }) {
    this.session = session;
    this.params = params;
    this.token = token;
    this.protocol = protocol;
    this.grid = grid;
    this.name = name;
    this.on = on;
    this.ws = null;
    this.refused = false; // the proxy said the token does not open the session
    this.me = null; // our participant id, from Welcome
    this.synced = false; // the history has arrived
    // Our strokes not yet done, oldest first, each {stroke, brush, device, samples, sent, acked,
    // ended}: every one is resumed after a reconnect, so a stroke whose end was lost with the
    // connection while the next was begun is ended all the same. The last is `pending`.
    this.unfinished = [];
    this.drawing = false; // the pen is down on `pending` in this page
    // Our strokes an old connection still holds: stroke -> the timer of the next try to take it
    // over here, or null while a try (a StrokeBegin) awaits its answer.
    this.takeOvers = new Map();
    // Our set_placement requests the proxy has not answered yet, per stroke (stroke -> count):
    // each is answered by a peer_placement of it, or refused by an error naming it.
    this.moving = new Map();
    this.wsBytes = 0; // payload bytes received (docs/performance.md)
    // How the page sends: "binary" (codec.js) or "json"; the proxy answers in the same form.
    this.encoding = "binary";
    this.retry = 500;
    this.lastFlush = 0;
    this.lastSent = 0;
    setInterval(() => {
      if (performance.now() - this.lastSent >= KEEPALIVE_MS) this.send({ ping: { nonce: 0 } });
    }, KEEPALIVE_MS / 4);
  }

  storageKey() {
    return `penmesh:${this.session}:pending`;
  }

  /// Our latest stroke not yet done (the one being drawn, if the pen is down), or null.
  get pending() {
    return this.unfinished.length ? this.unfinished[this.unfinished.length - 1] : null;
  }

  /// Our stroke `stroke` if it is not done yet.
  unfinishedStroke(stroke) {
    return this.unfinished.find((p) => p.stroke === stroke);
  }

  /// This tab's participant key (hello.key, and the x-penmesh-key header of the mesh build):
  /// 128 random bits, kept in sessionStorage beside the strokes not yet done, so a reconnect or
  /// a reload is the same participant and may resume them; another tab is another participant.
  participantKey() {
    const name = `penmesh:${this.session}:key`;
    let key = sessionStorage.getItem(name);
    if (!key) {
      const bytes = crypto.getRandomValues(new Uint8Array(16));
      key = Array.from(bytes, (b) => b.toString(16).padStart(2, "0")).join("");
      sessionStorage.setItem(name, key);
    }
    return key;
  }

  savePending() {
    if (this.unfinished.length) sessionStorage.setItem(this.storageKey(), JSON.stringify(this.unfinished));
    else sessionStorage.removeItem(this.storageKey());
  }

  /// The strokes not yet done that this tab kept (a list; an older page kept one stroke alone).
  loadPending() {
    const kept = JSON.parse(sessionStorage.getItem(this.storageKey()) || "[]");
    return Array.isArray(kept) ? kept : [kept];
  }

  connect() {
    const scheme = location.protocol === "https:" ? "wss" : "ws";
    // The token travels as a subprotocol: never in the URL, so never in an access log.
    const ws = new WebSocket(`${scheme}://${location.host}/v1/sessions/${this.session}/ws`, [
      "penmesh",
      `penmesh.token.${this.token}`,
    ]);
    this.ws = ws;
    ws.binaryType = "arraybuffer";
    ws.onopen = () => {
      this.retry = 500;
      for (const timer of this.takeOvers.values()) clearTimeout(timer);
      this.takeOvers.clear(); // the Hello resumes them all
      this.moving.clear(); // the old connection's answers never come; the history tells
      this.unfinished = this.loadPending();
      this.send({
        hello: {
          protocol: this.protocol,
          client: "penmesh-web",
          name: this.name,
          resume: this.unfinished.map((p) => p.stroke),
          key: this.participantKey(),
        },
      });
    };
    ws.onmessage = (e) => {
      if (typeof e.data === "string") {
        this.wsBytes += e.data.length;
        this.receive(JSON.parse(e.data));
        return;
      }
      this.wsBytes += e.data.byteLength;
      let message;
      try {
        message = decodeServer(e.data, this.protocol);
      } catch (err) {
        // A page or proxy bug, never the network's: said, and the frame left out.
        console.error(err);
        this.on("error", { code: "malformed", message: `a binary frame from the proxy does not decode: ${err.message}`, stroke: null });
        return;
      }
      this.receive(message);
    };
    ws.onclose = (e) => {
      this.ws = null;
      // The proxy's answer to a token that does not open the session: it will not change, so
      // no retry (a network failure is 1006, and is retried).
      if (e.code === UNAUTHORIZED) {
        this.refused = true;
        this.on("refused", { reason: e.reason });
        return;
      }
      this.on("closed", { code: e.code, reason: e.reason });
      setTimeout(() => this.connect(), this.retry);
      this.retry = Math.min(this.retry * 2, 10000);
    };
  }

  /// Sends `msg` when connected, in `encoding`; returns whether it went out. A message the
  /// codec cannot encode (a page bug: say a matrix with a NaN) is said, as the proxy would
  /// refuse it, and not sent.
  send(msg) {
    if (this.ws && this.ws.readyState === WebSocket.OPEN) {
      let frame;
      try {
        frame = this.encoding === "json" ? JSON.stringify(msg) : encodeClient(msg, this.protocol);
      } catch (err) {
        console.error(err);
        const [m] = Object.values(msg);
        this.on("error", { code: "malformed", message: `not sent: ${err.message}`, stroke: (m && m.stroke) || null });
        return false;
      }
      this.ws.send(frame);
      this.lastSent = performance.now();
      return true;
    }
    return false;
  }

  /// Asks the proxy to take back (`remove`) or bring back one of our finished strokes; it
  /// answers `stroke_removed` or `stroke_restored` (to every page of the session), or an error.
  /// Returns whether the request went out.
  setRemoved(stroke, remove) {
    return this.send(remove ? { remove_stroke: { stroke } } : { restore_stroke: { stroke } });
  }

  /// Our display name changed: told to the session now, and said in every later hello.
  rename(name) {
    this.name = name;
    this.send({ rename: { name } });
  }

  receive(msg) {
    const [kind, m] = Object.entries(msg)[0];
    switch (kind) {
      case "welcome":
        this.me = m.participant;
        this.on(kind, m);
        for (const p of [...this.unfinished]) this.resumeOwn(p, m.resume.find((r) => r.stroke === p.stroke));
        return;
      case "synced":
        this.synced = true;
        break;
      case "ack": {
        const p = this.unfinishedStroke(m.stroke);
        if (p) p.acked = m.upto_seq;
        if (p && this.takeOvers.get(m.stroke) === null) {
          this.takeOvers.delete(m.stroke);
          // Taken over on this connection: it has everything below upto_seq.
          this.resumeOwn(p, { status: "open", next_seq: m.upto_seq });
          return;
        }
        break;
      }
      case "retained":
        if (!this.unfinishedStroke(m.stroke)) return;
        break;
      case "stroke_done":
        return this.strokeDone(m.stroke);
      case "error":
        if (m.code === "lagged") this.synced = false;
        // Ours, held by an old connection (a resume or take-over refused), or not open here
        // (points sent for it meanwhile): taken over again later, handled here.
        if (m.code === "stroke_conflict" && this.unfinishedStroke(m.stroke)) {
          this.retakeLater(m.stroke);
          return;
        }
        if (m.code === "unknown_stroke" && this.unfinishedStroke(m.stroke)) {
          if (!this.takeOvers.has(m.stroke)) this.retakeLater(m.stroke);
          return;
        }
        if (m.stroke) this.moveAnswered(m.stroke); // a move refused is answered too
        break;
      case "peer_placement":
        // The answer to a move of ours that a later one has overtaken on this page: not shown.
        if (this.moveAnswered(m.stroke) > 0) return;
        break;
      case "peer_strokes":
        // A history's strokes, several to a message: each as its own events would say it
        // (penmesh::protocol::PeerStrokes::messages).
        for (const s of m.strokes) this.historyStroke(s);
        return;
      default:
        break;
    }
    this.on(kind, m);
  }

  historyStroke({ participant, stroke, brush, points, done, mesh, placement, solid }) {
    this.on("peer_stroke_begin", { participant, stroke, brush });
    // Version 6: its placement and solid ride along (absent in versions 5 and 4).
    if (placement && !isIdentity(placement.matrix)) this.on("peer_placement", { participant, stroke, placement });
    if (solid && (solid.kind !== "line" || solid.depth !== null)) this.on("peer_solid", { participant, stroke, solid });
    if (points.length) this.on("peer_retained", { participant, stroke, first: 0, points });
    if (!done) return;
    this.on("peer_stroke_done", { participant, stroke, n_retained: points.length, url: `/v1/strokes/${stroke}/simplified` });
    if (mesh) this.on("peer_mesh", { participant, stroke, url: `/v1/strokes/${stroke}/mesh` });
  }

  /// Whether our stroke `stroke` waits to be taken over on this connection: its samples and
  /// end are kept until then (the proxy would refuse them), and sent when it is.
  awaitingTakeOver(stroke) {
    return this.takeOvers.has(stroke);
  }

  /// Tries again in RETAKE_MS to take over our stroke `stroke` on this connection (a
  /// StrokeBegin of it: answered by an ack of what the proxy has, or by stroke_done), unless a
  /// try is already timed.
  retakeLater(stroke) {
    if (this.takeOvers.get(stroke)) return;
    const ws = this.ws;
    this.takeOvers.set(
      stroke,
      setTimeout(() => {
        const p = this.unfinishedStroke(stroke);
        if (!p || this.ws !== ws) {
          this.takeOvers.delete(stroke);
          return;
        }
        this.takeOvers.set(stroke, null);
        this.send({ stroke_begin: strokeBegin(p) });
      }, RETAKE_MS),
    );
  }

  strokeDone(stroke) {
    clearTimeout(this.takeOvers.get(stroke));
    this.takeOvers.delete(stroke);
    const before = this.unfinished.length;
    this.unfinished = this.unfinished.filter((p) => p.stroke !== stroke);
    if (this.unfinished.length !== before) this.savePending();
    this.on("stroke_done", { stroke });
  }

  // After a reconnect (or a reload) the proxy says how far it has one of our strokes: send the
  // rest from there, then end it unless the pen is still down on it (a reload lifts it: the pen
  // cannot come back to a page that went away).
  resumeOwn(p, r) {
    if (!r || r.status === "unknown") {
      // Never reached the proxy: begin it again with everything.
      this.send({ stroke_begin: strokeBegin(p) });
      r = { next_seq: 0, status: "open" };
    }
    if (r.status === "done") return this.strokeDone(p.stroke);
    const penDown = this.drawing && p === this.pending;
    if (!penDown && p.held) {
      p.samples.push(p.held); // the pen lifted (or the page went away) on a rest
      p.held = null;
    }
    if (this.awaitingTakeOver(p.stroke)) {
      // Refused for now (its error came before this welcome): sent once it is taken over.
      if (!penDown) p.ended = true;
      this.savePending();
      return;
    }
    const rest = p.samples.slice(r.next_seq);
    if (rest.length) this.send({ points: { stroke: p.stroke, seq: r.next_seq, points: rest } });
    p.sent = p.samples.length;
    if (!penDown) {
      p.ended = true;
      this.savePending();
      this.send({ stroke_end: { stroke: p.stroke, n_points: p.samples.length } });
    }
  }

  /// Whether a new stroke may begin: we are in the session, our last stroke has ended and
  /// fewer than MAX_UNFINISHED of ours wait to be done.
  canBegin() {
    const last = this.pending;
    return Boolean(this.me) && !this.drawing && !(last && !last.ended) && this.unfinished.length < MAX_UNFINISHED;
  }

  /// Begins our stroke on the work plane `placement` (16 numbers; null: the board), to become
  /// `solid` (`{kind, depth}`; null: the rod); returns its id.
  begin(brush, device, placement = null, solid = null) {
    const stroke = crypto.randomUUID();
    const params = this.paramsFor(brush);
    this.unfinished.push({ stroke, brush, device, params, placement, solid, samples: [], sent: 0, acked: 0, ended: false });
    this.drawing = true;
    this.send({ stroke_begin: strokeBegin(this.unfinished[this.unfinished.length - 1]) });
    return stroke;
  }

  /// Asks the proxy to place our finished stroke at `placement` (16 numbers); it answers with
  /// `peer_placement` (to every page), or an error. Returns whether the request went out.
  setPlacement(stroke, placement) {
    const sent = this.send({ set_placement: { stroke, placement: { matrix: placement } } });
    if (sent) this.moving.set(stroke, (this.moving.get(stroke) || 0) + 1);
    return sent;
  }

  /// The oldest of our moves of `stroke` not yet answered has been: how many are left.
  moveAnswered(stroke) {
    const left = (this.moving.get(stroke) || 0) - 1;
    if (left > 0) this.moving.set(stroke, left);
    else this.moving.delete(stroke);
    return Math.max(left, 0);
  }

  /// The ACUTS parameters of a stroke drawn with `brush`: the proxy's, with a pressure
  /// tolerance of WIDTH_TOLERANCE_PX of width (2 E chi delta_p) when that is tighter.
  paramsFor(brush) {
    const [tolerance, angle, pressure] = this.params;
    const perPressure = 2 * brush.size * brush.pressure_response;
    const tight = perPressure > 0 ? Math.max(MIN_PRESSURE_TOLERANCE, WIDTH_TOLERANCE_PX / perPressure) : pressure;
    return { tolerance, angle_deg: angle, angle_near_anchor: false, pressure: { interpolation: Math.min(pressure, tight) } };
  }

  /// One sample of our stroke: `t` in ms since pen-down. Snapped to the grid; time never goes
  /// backwards (coalesced events can share a timestamp). Stage 1's repeat rule, as the native
  /// client's (penmesh::Resampler, docs/web.md): a sample equal in x, y and pressure to the last
  /// one kept (a pen at rest) is held back, and kept only as the rest's last sample when the
  /// pen leaves it with another pressure, or at pen-up: this costs no error.
  add(x, y, t, p) {
    const [position, time, pressure] = this.grid;
    const pending = this.pending;
    const samples = pending.samples;
    const last = samples[samples.length - 1];
    const latest = pending.held || last;
    const sample = [snap(x, position), snap(y, position), Math.max(latest ? latest[2] : 0, snap(t, time)), snap(p, pressure)];
    if (last && sample[0] === last[0] && sample[1] === last[1] && sample[3] === last[3]) {
      pending.held = sample;
      return;
    }
    if (pending.held && pending.held[3] !== sample[3]) samples.push(pending.held);
    pending.held = null;
    samples.push(sample);
  }

  /// Keeps every sample for a reload, and sends the unsent ones when `force` or FLUSH_MS have
  /// passed since the last send.
  flush(force) {
    const p = this.pending;
    const now = performance.now();
    if (!p) return;
    this.savePending(); // every sample survives a reload, sent or not
    if (!force && now - this.lastFlush < FLUSH_MS) return;
    this.lastFlush = now;
    if (p.sent < p.samples.length && !this.awaitingTakeOver(p.stroke)) {
      this.send({ points: { stroke: p.stroke, seq: p.sent, points: p.samples.slice(p.sent) } });
      p.sent = p.samples.length;
    }
  }

  /// Pen-up: sends what is left and ends our stroke.
  end() {
    const p = this.pending;
    this.drawing = false;
    p.ended = true;
    if (p.held) {
      p.samples.push(p.held); // the pen-up sample is always sent
      p.held = null;
    }
    this.flush(true);
    if (!this.awaitingTakeOver(p.stroke)) this.send({ stroke_end: { stroke: p.stroke, n_points: p.samples.length } });
  }
}

/// The `stroke_begin` of one of our strokes (`unfinished`'s entry): its placement and solid only
/// when it has them (a stroke kept by an older page has none: the board, the rod).
function strokeBegin({ stroke, brush, device, params, placement, solid }) {
  return { stroke, brush, device, params, ...(placement ? { placement: { matrix: placement } } : {}), ...(solid ? { solid } : {}) };
}

/// Whether a placement's 16 numbers are the identity (the board).
function isIdentity(matrix) {
  return matrix.every((v, i) => v === (i % 5 === 0 ? 1 : 0));
}
