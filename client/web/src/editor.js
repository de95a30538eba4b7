// The editor: the state the page's controls act on, in one object: the active tool (one at a
// time, tools.js), the camera (the view's, camera.js), the history of our strokes (takeback.js)
// and the brush; it says what changed through signals (`on(name, fn)`): "tool", "camera",
// "history", "notice" (a sentence for the person: an action that did nothing, and why).
// The tools act through its methods; the entry module (app.js) only wires.
import { createTools } from "./tools.js";

// Half the eraser's width, in CSS pixels.
export const ERASER_RADIUS_PX = 8;

export class Editor {
  /// `conn`: the connection (protocol.js); `view`: the 3D view; `ink`; `takeBack`; `brush`;
  /// `people`: participant -> name.
  constructor({ conn, view, ink, takeBack, brush, people }) {
    Object.assign(this, { conn, view, ink, takeBack, brush, people });
    this.listeners = new Map();
    this.tools = createTools();
    this.tool = this.tools.draw;
    this.penUpAt = new Map(); // our stroke -> performance.now() at pen-up
    this.takeBack.onChange = () => this.emit("history");
  }

  on(name, fn) {
    if (!this.listeners.has(name)) this.listeners.set(name, []);
    this.listeners.get(name).push(fn);
  }

  emit(name, ...args) {
    for (const fn of this.listeners.get(name) || []) fn(...args);
  }

  notice(text) {
    this.emit("notice", text);
  }

  /// Makes tool `id` the one active tool: the old one's `onExit`, the new one's `onEnter`.
  setTool(id) {
    const next = this.tools[id];
    if (!next || next === this.tool) return;
    this.tool.onExit(this);
    this.tool = next;
    next.onEnter(this);
    this.emit("tool", next);
  }

  // --- the camera (any tool: the dispatcher calls these before the tool sees anything) ------
  zoomAt(x, y, factor) {
    this.view.rig.zoomAt(x, y, factor);
    this.cameraMoved();
  }

  panBy(from, to) {
    this.view.rig.panBy(from, to);
    this.cameraMoved();
  }

  orbitBy(dx, dy) {
    this.view.rig.orbitBy(dx, dy);
    this.cameraMoved();
  }

  /// The front view of the whole drawing (the one explicit reset of the camera).
  fit() {
    this.view.fitToDrawing();
    this.cameraMoved();
  }

  /// Named view `name` (camera.js VIEWS) of the whole drawing.
  look(name) {
    this.view.look(name);
    this.cameraMoved();
  }

  cameraMoved() {
    this.view.cameraMoved();
    this.ink.redraw();
    this.emit("camera");
  }

  // --- drawing -------------------------------------------------------------------------------
  /// Begins a stroke of ours at the first of `samples` ({clientX, clientY, t, p}); false (and
  /// a notice) when it cannot begin now.
  beginStroke(device, samples) {
    if (!this.conn.canBegin()) {
      this.notice(this.conn.ws ? "wait a moment: your last strokes are still being stored" : "cannot draw: not connected to the proxy; trying again");
      return false;
    }
    // On the work plane (workplane.js): the stroke's placement from its begin.
    const placement = this.view.workPlacement;
    // What it becomes (drawsolid.js: null, the rod, unless Filled or Hole is chosen).
    const solid = this.drawSolid || null;
    const stroke = this.conn.begin({ ...this.brush }, device, placement, solid);
    this.view.stroke(stroke, this.conn.me, this.brush);
    if (solid) this.view.setSolid(stroke, this.conn.me, solid);
    if (placement) this.view.setPlacement(stroke, placement);
    this.ink.begin(stroke);
    this.strokeSamples(samples, true);
    return true;
  }

  /// More samples of the stroke being drawn.
  strokeSamples(samples, first = false) {
    const stroke = this.conn.pending.stroke;
    for (const s of samples) {
      const at = this.view.toStroke(s.clientX, s.clientY);
      if (!at) continue;
      this.conn.add(at[0], at[1], s.t, s.p);
      this.ink.add(stroke, at[0], at[1], s.p);
    }
    this.conn.flush(first);
    this.ink.redraw();
  }

  endStroke() {
    const stroke = this.conn.pending.stroke;
    this.conn.end();
    this.penUpAt.set(stroke, performance.now());
  }

  // --- erasing -------------------------------------------------------------------------------
  /// Erases our strokes under page point (`x`, `y`), whatever their plane; `drag` (one per
  /// eraser drag) collects whose strokes it touched, for one notice when they were only the
  /// others', and makes what it erased one command of the history (takeback.js).
  eraseAt(x, y, drag) {
    if (!this.conn.me) return;
    for (const stroke of this.view.strokesUnder(x, y, ERASER_RADIUS_PX)) {
      const owner = this.view.strokes.get(stroke).participant;
      if (owner !== this.conn.me) {
        if (!drag.others.has(owner)) {
          drag.others.add(owner);
          this.notice(`that stroke is ${this.people.get(owner) || "someone else"}'s: you can erase only your own`);
        }
      } else if (!this.takeBack.erase(stroke, drag)) {
        this.notice("cannot erase: not connected to the proxy; try again");
      }
    }
  }

  // --- the work plane -------------------------------------------------------------------------
  /// The Plane tool's click at page point (`x`, `y`): the work plane on the stroke there, or on
  /// the board through the ground's point there; then back to drawing.
  pickWorkPlane(x, y) {
    const selection = this.selection;
    const id = selection.rayPick(x, y) ?? selection.nearestPick(x, y);
    if (id) {
      this.workPlane.set("stroke", this.view.strokes.get(id).placement);
      this.notice("drawing on that stroke's plane");
    } else {
      const at = this.view.rig.toPlane(x, y);
      if (!at) return this.notice("nothing there: click a stroke or the ground");
      this.workPlane.set("board");
      this.workPlane.groundPoint = at;
      this.notice("drawing on the board (Front or Side next go through where you clicked)");
    }
    this.setTool("draw");
  }

  // --- undo and redo -------------------------------------------------------------------------
  get canUndo() {
    return this.takeBack.undone.length > 0;
  }

  get canRedo() {
    return this.takeBack.redone.length > 0;
  }

  undo() {
    this.undoOrRedo(false);
  }

  redo() {
    this.undoOrRedo(true);
  }

  undoOrRedo(redo) {
    if (!(redo ? this.canRedo : this.canUndo)) {
      this.notice(redo ? "nothing to redo" : "nothing to undo: only your own strokes can be taken back");
      return;
    }
    const done = redo ? this.takeBack.redo() : this.takeBack.undo();
    if (!done) this.notice(`cannot ${redo ? "redo" : "undo"}: not connected to the proxy; try again`);
  }
}
