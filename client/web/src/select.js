// Select: the tool (V) and the selection it makes. A click picks the stroke under the pointer
// (shift adds or drops it), a drag on nothing draws a box and picks every stroke inside it. The
// selected strokes are lifted out of their group's merged meshes (scene.js `liftOut`) and a
// three.js TransformControls gizmo moves or turns them about their centre, snapping to the grid
// and to 15° steps when snapping is on. The gizmo gets its pointer from this tool (input.js's
// one dispatcher, so the camera's gestures stay the camera's), never from the DOM. A drag
// applies at once; at its end every stroke it moved is sent (`set_placement`) and the drag is
// one command of the page's one history (takeback.js): undo sends each placement it had before,
// exactly, redo the one after. Duplicate (Ctrl/Cmd+D) copies the selection over HTTP in place,
// or moved again by the move given to the last copies (TinkerCAD's repeat); its undo takes the
// copies back. Typed numbers, turns, drop to the plane, nudges and Delete are one command each
// (the selection's panel, selpanel.js, and the keys, modelbar.js). Mirror reflects the selection across
// the plane through its centre across the work plane's x axis. Only one's own strokes move:
// the proxy refuses the others' (`not_owner`), and the page says so first.
import * as THREE from "three";
import { TransformControls } from "three/examples/jsm/controls/TransformControls.js";
import { IDENTITY, matrixOf, placementOf, planeThrough } from "./placement.js";
import { GRID_SNAP } from "./workplane.js";

// A click picks a stroke that passes this near (CSS px) beyond its own width.
const PICK_PX = 6;
// A pointer that moves this far (CSS px) before it lifts draws a box instead of clicking.
const BOX_SLOP_PX = 4;
// Turns snap to this step when snapping is on.
const ROTATION_SNAP = THREE.MathUtils.degToRad(15);
// The session's y is down, the scene's up (scene.js `world`).
const FLIP = new THREE.Matrix4().makeScale(1, -1, 1);

export class Selection {
  /// `editor` (editor.js: its view, connection, history); `api` (api.js: duplicate);
  /// `workPlane` (workplane.js).
  constructor(editor, { api, workPlane }) {
    this.editor = editor;
    this.view = editor.view;
    this.api = api;
    this.workPlane = workPlane;
    this.ids = new Set();
    this.snap = false;
    this.onChange = () => {}; // the selection or the snap changed
    this.picking = null; // the points picked so far of a plane through three points, or null
    this.repeat = null; // {copies, origin: copy -> its source's placement}: the last duplicate
    this.pivot = new THREE.Object3D(); // the gizmo's object, at the selection's centre
    this.view.scene.add(this.pivot);
    this.gizmo = new TransformControls(this.view.camera);
    this.gizmo.addEventListener("change", () => this.view.requestRender());
    this.gizmo.addEventListener("objectChange", () => this.dragged());
    this.view.scene.add(this.gizmo.getHelper());
    this.boxes = new Map(); // stroke -> its BoxHelper while selected
    this.drag = null; // {pivot: matrix at its start, before: stroke -> placement}
    // The handle under a hovering mouse or pen is lit (it only looks: the dispatcher, input.js,
    // still owns every press).
    document.getElementById("ink").addEventListener("pointermove", (e) => {
      if (this.gizmo.object && !this.drag && e.buttons === 0 && e.pointerType !== "touch") this.gizmo.pointerHover(this.pointer(e.clientX, e.clientY, 0));
    });
  }

  get list() {
    return [...this.ids];
  }

  /// Says the selection, its placements or its modes changed: `onChange` and the editor's
  /// "selection" signal (the selection's panel listens).
  changed() {
    this.onChange(this);
    this.editor.emit("selection", this);
  }

  /// The selection becomes `ids`: strokes no longer in it are put back, new ones lifted out.
  set(ids) {
    const next = new Set(ids.filter((id) => this.view.liftOut(id)));
    for (const id of this.ids) {
      if (next.has(id)) continue;
      this.view.putBack(id);
      this.view.scene.remove(this.boxes.get(id));
      this.boxes.get(id).dispose();
      this.boxes.delete(id);
    }
    for (const id of next) {
      if (this.boxes.has(id)) continue;
      const box = new THREE.BoxHelper(this.view.strokes.get(id).lifted, 0xf0a000);
      this.boxes.set(id, box);
      this.view.scene.add(box);
    }
    this.ids = next;
    this.refresh();
    this.changed();
  }

  clear() {
    this.set([]);
  }

  /// Our own strokes among the selected (the only ones that can move).
  own() {
    return this.list.filter((id) => this.view.strokes.get(id).participant === this.editor.conn.me);
  }

  /// The gizmo at the selection's centre, shown when the selection is ours to move; the boxes
  /// around the strokes where they are now.
  refresh() {
    if (this.drag) return;
    // A stroke taken back (an undone duplicate, another page's undo) leaves the selection.
    if (this.list.some((id) => this.view.strokes.get(id).removed)) return this.set(this.list.filter((id) => !this.view.strokes.get(id).removed));
    for (const [id, box] of this.boxes) {
      box.setFromObject(this.view.strokes.get(id).lifted);
      box.visible = this.view.strokes.get(id).lifted.visible;
    }
    const centre = this.centre();
    if (!centre) {
      this.gizmo.detach();
      this.view.requestRender();
      return;
    }
    this.pivot.position.copy(centre).applyMatrix4(FLIP);
    this.pivot.quaternion.identity();
    this.pivot.scale.set(1, 1, 1);
    this.pivot.updateMatrixWorld(true);
    if (this.own().length === this.ids.size) this.gizmo.attach(this.pivot);
    else this.gizmo.detach();
    // (Moves snap by the selection's bounds, dragged(); turns by 15° steps.)
    this.gizmo.setRotationSnap(this.snap ? ROTATION_SNAP : null);
    this.view.requestRender();
    this.changed();
  }

  /// The centre of the selected strokes' boxes, in session space (null when nothing is).
  centre() {
    const box = new THREE.Box3();
    for (const id of this.ids) {
      const s = this.view.strokes.get(id);
      if (s.lifted) box.expandByObject(s.lifted);
    }
    return box.isEmpty() ? null : box.getCenter(new THREE.Vector3()).applyMatrix4(FLIP);
  }

  setSnap(on) {
    this.snap = on;
    this.refresh();
    this.changed();
  }

  /// The gizmo moves (`translate`) or turns (`rotate`) about one axis at a time, `axis` ("X",
  /// "Y" or "Z" of the scene; three.js colours its ring red, green, blue).
  setMode(mode, axis = "Z") {
    this.gizmo.setMode(mode);
    const one = mode === "rotate";
    this.gizmo.showX = !one || axis === "X";
    this.gizmo.showY = !one || axis === "Y";
    this.gizmo.showZ = !one || axis === "Z";
    this.turnAxis = one ? axis : null;
    this.view.requestRender();
    this.changed();
  }

  // --- picking ---------------------------------------------------------------------------------
  /// The stroke under page point (`x`, `y`): the first whose mesh the pointer's ray meets (of
  /// strokes on one line seen from above, such as a wall standing on the floor's edge, the one
  /// nearer the camera), else the nearest within its width and PICK_PX on the page (a thin
  /// stroke), else null.
  pick(x, y) {
    return this.rayPick(x, y) ?? this.nearestPick(x, y);
  }

  /// The shown stroke whose mesh the ray through page point (`x`, `y`) meets first, or null.
  rayPick(x, y) {
    const hit = this.rayHit(x, y);
    if (!hit) return null;
    for (const [id, s] of this.view.strokes) {
      if (s.removed || !s.mesh) continue;
      if (s.lifted === hit.object) return id;
      const r = s.mesh;
      if (!s.lifted && r.group.mesh === hit.object && hit.face.a >= r.firstVertex && hit.face.a < r.firstVertex + r.vertexCount) return id;
    }
    return null;
  }

  /// The first intersection of the ray through page point (`x`, `y`) with the strokes' meshes.
  rayHit(x, y) {
    const ray = new THREE.Raycaster();
    ray.setFromCamera(new THREE.Vector2((x / this.view.rig.width) * 2 - 1, -(y / this.view.rig.height) * 2 + 1), this.view.camera);
    // Where each object is now: three.js works out world matrices when it renders, and a group
    // made for a stroke just moved (batch.js) has none until the next frame.
    this.view.scene.updateMatrixWorld();
    const meshes = [];
    for (const mesh of this.view.groups.objects) {
      mesh.geometry.boundingSphere = null; // it grew since: worked out again
      meshes.push(mesh);
    }
    for (const s of this.view.strokes.values()) if (s.lifted && !s.removed) meshes.push(s.lifted);
    return ray.intersectObjects(meshes, false)[0] || null;
  }

  /// The shown, finished stroke with a mesh nearest to page point (`x`, `y`) within its width
  /// and PICK_PX, or null: its retained points projected through its placement.
  nearestPick(x, y) {
    let best = null;
    let bestDistance = Infinity;
    const scale = this.view.pixelsPerUnit();
    for (const [id, s] of this.view.strokes) {
      if (s.removed || !s.mesh) continue;
      const reach = PICK_PX + (s.brush ? s.brush.size / 2 : 4) * scale;
      const page = s.points.map((p) => this.view.toPage(p.x, p.y, s.placement));
      for (let i = 0; i < page.length; i++) {
        const d = segmentDistance([x, y], page[i], page[Math.min(i + 1, page.length - 1)]);
        if (d <= reach && d < bestDistance) {
          best = id;
          bestDistance = d;
        }
      }
    }
    return best;
  }

  /// Every shown stroke with a mesh whose retained points are all inside the page rectangle.
  inBox(x0, y0, x1, y1) {
    const [left, right, top, bottom] = [Math.min(x0, x1), Math.max(x0, x1), Math.min(y0, y1), Math.max(y0, y1)];
    const inside = ([x, y]) => x >= left && x <= right && y >= top && y <= bottom;
    const ids = [];
    for (const [id, s] of this.view.strokes) {
      if (s.removed || !s.mesh || s.points.length === 0) continue;
      if (s.points.every((p) => inside(this.view.toPage(p.x, p.y, s.placement)))) ids.push(id);
    }
    return ids;
  }

  /// The point of the model under page point (`x`, `y`), in session space: on a stroke's mesh,
  /// else on the work plane; null when neither is there.
  pointAt(x, y) {
    const hit = this.rayHit(x, y);
    if (hit) return hit.point.applyMatrix4(FLIP);
    const at = this.view.toStroke(x, y);
    return at ? new THREE.Vector3(at[0], at[1], 0).applyMatrix4(matrixOf(this.view.workPlacement)) : null;
  }

  /// Starts picking the plane through three points (the next three clicks of this tool).
  pickPlane() {
    this.editor.setTool("select");
    this.clear(); // no handles in the way of the clicks
    this.picking = [];
    this.editor.notice("click three points of the model: the work plane goes through them");
  }

  /// One point of the plane through three points picked at page point (`x`, `y`).
  pickPoint(x, y) {
    const p = this.pointAt(x, y);
    if (!p) return this.editor.notice("nothing there to pick: click on a stroke or the grid");
    this.picking.push(p);
    if (this.picking.length < 3) return this.editor.notice(`point ${this.picking.length} of 3`);
    const placement = planeThrough(...this.picking);
    this.picking = null;
    if (!placement) return this.editor.notice("those three points are on one line: no plane through them");
    this.workPlane.set("points", placement);
    this.editor.notice("the work plane goes through your three points");
  }

  // --- the gizmo -------------------------------------------------------------------------------
  /// The gizmo's pointer, from page point (`x`, `y`): normalised device coordinates.
  pointer(x, y, button) {
    return { x: (x / this.view.rig.width) * 2 - 1, y: -(y / this.view.rig.height) * 2 + 1, button };
  }

  /// Where on the page (CSS px) the gizmo's handle for `axis` is: moving ("X", "Y", "Z",
  /// "XY", …), its picker's middle; turning ("Z" only: its ring lies in the scene's x-y), a
  /// point of its ring. Null without a gizmo (the browser tests drag it).
  handleAt(axis) {
    if (!this.gizmo.object) return null;
    this.gizmo.getHelper().updateMatrixWorld(true);
    const picker = this.gizmo._gizmo.picker[this.gizmo.mode].children.find((c) => c.name === axis);
    if (!picker) return null;
    const box = new THREE.Box3().setFromObject(picker, true);
    const at = box.getCenter(new THREE.Vector3());
    if (this.gizmo.mode === "rotate") {
      // The ring's middle radius (three.js's picker torus: 0.5 with a 0.1 tube), at 45°.
      const r = (((box.max.x - box.min.x) / 2) * 5) / 6;
      at.x += r * Math.SQRT1_2;
      at.y += r * Math.SQRT1_2;
    }
    at.project(this.view.camera);
    return [((at.x + 1) / 2) * this.view.rig.width, ((1 - at.y) / 2) * this.view.rig.height];
  }

  /// A pointer went down at (`x`, `y`): true when it is on a handle of the gizmo, whose drag it
  /// begins (the placements before it recorded).
  grab(x, y) {
    if (!this.gizmo.object) return false;
    this.gizmo.pointerHover(this.pointer(x, y, 0));
    // The gizmo's drag plane turned to the handle hovered before the drag starts on it (three.js
    // does this in the frame between a hover and a press).
    this.gizmo.getHelper().updateMatrixWorld(true);
    this.gizmo.pointerDown(this.pointer(x, y, 0));
    if (!this.gizmo.dragging) return false;
    this.drag = { pivot: this.pivot.matrixWorld.clone(), before: new Map(this.list.map((id) => [id, this.view.strokes.get(id).placement])) };
    return true;
  }

  moveGrab(x, y) {
    this.gizmo.pointerMove(this.pointer(x, y, -1));
  }

  /// The gizmo moved the pivot: each stroke by the same motion, at once on this page.
  dragged() {
    if (!this.drag) return;
    this.pivot.updateMatrixWorld(true);
    // The pivot's motion in the scene, as a motion of session space: FLIP·D·FLIP.
    const motion = this.pivot.matrixWorld.clone().multiply(this.drag.pivot.clone().invert());
    let session = FLIP.clone().multiply(motion).multiply(FLIP);
    if (this.snap && this.gizmo.mode === "translate") session = this.snappedByBounds(session);
    for (const [id, before] of this.drag.before) this.view.setPlacement(id, placementOf(session.clone().multiply(matrixOf(before))));
    for (const [id, box] of this.boxes) box.setFromObject(this.view.strokes.get(id).lifted);
    this.showReadout(session);
    this.changed();
  }

  /// `motion` moved on so that the selection's box, moved by it, has its low corner on the grid
  /// along each axis the gizmo drags (TinkerCAD snaps by the bounds, not the centre: a wall's
  /// foot lands on a grid line).
  snappedByBounds(motion) {
    const box = new THREE.Box3();
    const v = new THREE.Vector3();
    for (const [id, before] of this.drag.before) {
      const m = motion.clone().multiply(matrixOf(before));
      for (const p of this.view.strokes.get(id).points) box.expandByPoint(v.copy(p).applyMatrix4(m));
    }
    const axis = this.gizmo.axis || "";
    const shift = [0, 1, 2].map((k) => (axis.includes("XYZ"[k]) ? Math.round(box.min.getComponent(k) / GRID_SNAP) * GRID_SNAP - box.min.getComponent(k) : 0));
    return new THREE.Matrix4().makeTranslation(...shift).multiply(motion);
  }

  /// The drag's distance (or angle) beside the gizmo, in plane units and the print's mm.
  showReadout(motion) {
    let el = document.getElementById("gizmo-readout");
    if (!el) {
      el = document.createElement("div");
      el.id = "gizmo-readout";
      el.style.cssText = "position:fixed;padding:2px 6px;background:#333;color:#fff;border-radius:4px;font:13px system-ui,sans-serif;pointer-events:none";
      document.body.append(el);
    }
    if (this.gizmo.mode === "rotate") {
      const q = new THREE.Quaternion().setFromRotationMatrix(motion);
      el.textContent = `${(THREE.MathUtils.radToDeg(2 * Math.acos(Math.min(1, Math.abs(q.w))))).toFixed(1)}°`;
    } else {
      const t = new THREE.Vector3().setFromMatrixPosition(motion);
      el.textContent = `${t.length().toFixed(1)} px · ${(t.length() * this.view.mmPerUnit()).toFixed(1)} mm`;
    }
    const [x, y] = this.view.rig.toPage(...this.centre().toArray());
    Object.assign(el.style, { left: `${x + 40}px`, top: `${y + 40}px`, display: "block" });
  }

  hideReadout() {
    const el = document.getElementById("gizmo-readout");
    if (el) el.style.display = "none";
  }

  /// The drag ended: its placements sent, one command in the history.
  letGo() {
    this.gizmo.pointerUp(this.pointer(0, 0, 0));
    this.hideReadout();
    const drag = this.drag;
    this.drag = null;
    if (!drag) return;
    const after = new Map([...drag.before.keys()].map((id) => [id, this.view.strokes.get(id).placement]));
    if ([...after].every(([id, m]) => same(m, drag.before.get(id)))) return this.refresh();
    this.place(after);
    this.editor.takeBack.push({ undo: () => this.place(drag.before), redo: () => this.place(after) });
    this.refresh();
  }

  /// Sends and shows placements (stroke -> 16 numbers or null, the board): false when the
  /// connection is down (nothing changes then).
  place(placements) {
    if (!this.editor.conn.ws) return false;
    for (const [id, placement] of placements) {
      this.editor.conn.setPlacement(id, placement || [...IDENTITY]);
      this.view.setPlacement(id, placement);
    }
    this.refresh();
    return true;
  }

  // --- mirror and duplicate -------------------------------------------------------------------
  /// Mirrors the selection across the plane through its centre perpendicular to the work
  /// plane's x axis; one command.
  mirror() {
    if (!this.ids.size) return this.editor.notice("select strokes first (V, then click or drag a box)");
    if (this.own().length !== this.ids.size) return this.editor.notice("you can mirror only your own strokes");
    const centre = this.centre();
    const axis = new THREE.Vector3().setFromMatrixColumn(matrixOf(this.view.workPlacement), 0).normalize();
    // A reflection: I - 2·u·uᵀ about the centre.
    const u = axis;
    const r = new THREE.Matrix4().set(
      1 - 2 * u.x * u.x, -2 * u.x * u.y, -2 * u.x * u.z, 0,
      -2 * u.y * u.x, 1 - 2 * u.y * u.y, -2 * u.y * u.z, 0,
      -2 * u.z * u.x, -2 * u.z * u.y, 1 - 2 * u.z * u.z, 0,
      0, 0, 0, 1,
    );
    const about = new THREE.Matrix4().makeTranslation(centre.x, centre.y, centre.z).multiply(r).multiply(new THREE.Matrix4().makeTranslation(-centre.x, -centre.y, -centre.z));
    const before = new Map(this.list.map((id) => [id, this.view.strokes.get(id).placement]));
    const after = new Map([...before].map(([id, m]) => [id, placementOf(about.clone().multiply(matrixOf(m)))]));
    if (!this.place(after)) return this.editor.notice("cannot mirror: not connected to the proxy; try again");
    this.editor.takeBack.push({ undo: () => this.place(before), redo: () => this.place(after) });
  }

  /// Duplicates the selection (anyone's strokes): each copy a new stroke of ours, in place
  /// (TinkerCAD's Ctrl+D); when the selection is the last copies and they were moved since,
  /// the copies land moved once more by that same motion (a row of posts, a circle of petals).
  /// The copies are selected once they are shown. One command: undo takes them back.
  async duplicate() {
    if (!this.ids.size) return this.editor.notice("select strokes first (V, then click or drag a box)");
    const conn = this.editor.conn;
    const motion = this.repeatMotion();
    const copies = [];
    const origin = new Map(); // copy -> the placement it was made with
    try {
      for (const id of this.list) {
        const placement = placementOf(motion.clone().multiply(matrixOf(this.view.strokes.get(id).placement)));
        const copy = await this.api.duplicate(id, crypto.randomUUID(), placement, conn.participantKey());
        copies.push(copy);
        origin.set(copy, this.view.strokes.get(id).placement);
      }
    } catch (err) {
      this.editor.notice(`cannot duplicate: ${err.message}`);
    }
    if (!copies.length) return;
    this.repeat = { copies, origin };
    const remove = (removed) => copies.every((id) => conn.setRemoved(id, removed));
    this.editor.takeBack.push({ undo: () => remove(true), redo: () => remove(false) });
    // Selected when their meshes are shown (they come over the connection as any stroke).
    const shown = () => copies.every((id) => this.view.hasMesh(id));
    for (let i = 0; i < 100 && !shown(); i++) await new Promise((r) => setTimeout(r, 50));
    this.set(copies.filter((id) => this.view.hasMesh(id)));
  }

  /// The motion the next duplicate repeats: how the last copies (when they are the selection)
  /// moved from where their sources were; none otherwise.
  repeatMotion() {
    const none = new THREE.Matrix4();
    const r = this.repeat;
    if (!r || r.copies.length !== this.ids.size || !r.copies.every((id) => this.ids.has(id))) return none;
    const [first] = r.copies;
    const now = this.view.strokes.get(first).placement;
    return matrixOf(now).multiply(matrixOf(r.origin.get(first)).invert());
  }

  // --- placing by numbers, keys ----------------------------------------------------------------
  /// The box of the selected strokes' retained points, placed (session space); empty when
  /// nothing is selected. The numbers of the selection's panel are its.
  bounds() {
    const box = new THREE.Box3();
    const v = new THREE.Vector3();
    for (const id of this.ids) {
      const s = this.view.strokes.get(id);
      const m = matrixOf(s.placement);
      for (const p of s.points) box.expandByPoint(v.copy(p).applyMatrix4(m));
    }
    return box;
  }

  /// Moves the selection by `motion` (a THREE.Matrix4 of session space): one command, sent at
  /// once; `what` names it in a notice when it cannot be done. False when nothing moved.
  moveBy(motion, what) {
    if (!this.ids.size) {
      this.editor.notice("select strokes first (V, then click or drag a box)");
      return false;
    }
    if (this.own().length !== this.ids.size) {
      this.editor.notice(`you can ${what} only your own strokes`);
      return false;
    }
    const before = new Map(this.list.map((id) => [id, this.view.strokes.get(id).placement]));
    const after = new Map([...before].map(([id, m]) => [id, placementOf(motion.clone().multiply(matrixOf(m)))]));
    if ([...after].every(([id, m]) => same(m, before.get(id)))) return false;
    if (!this.place(after)) {
      this.editor.notice(`cannot ${what}: not connected to the proxy; try again`);
      return false;
    }
    this.editor.takeBack.push({ undo: () => this.place(before), redo: () => this.place(after) });
    return true;
  }

  /// Moves the selection by (`dx`, `dy`, `dz`) of session space.
  translate(dx, dy, dz, what = "move") {
    return this.moveBy(new THREE.Matrix4().makeTranslation(dx, dy, dz), what);
  }

  /// Turns the selection by `degrees` about the session's `axis` ("x", "y" or "z") through
  /// the centre of its box.
  turn(axis, degrees) {
    const c = this.bounds().getCenter(new THREE.Vector3());
    const r = new THREE.Matrix4().makeRotationAxis(new THREE.Vector3(axis === "x" ? 1 : 0, axis === "y" ? 1 : 0, axis === "z" ? 1 : 0), THREE.MathUtils.degToRad(degrees));
    const about = new THREE.Matrix4().makeTranslation(c.x, c.y, c.z).multiply(r).multiply(new THREE.Matrix4().makeTranslation(-c.x, -c.y, -c.z));
    return this.moveBy(about, "turn");
  }

  /// Drops the selection onto the work plane (TinkerCAD's D): its lowest point along the
  /// plane's normal lands on the plane.
  dropToPlane() {
    const m = matrixOf(this.view.workPlacement);
    const origin = new THREE.Vector3().setFromMatrixPosition(m);
    const normal = new THREE.Vector3().setFromMatrixColumn(m, 2).normalize();
    let low = Infinity;
    const v = new THREE.Vector3();
    for (const id of this.ids) {
      const s = this.view.strokes.get(id);
      const placed = matrixOf(s.placement);
      for (const p of s.points) low = Math.min(low, v.copy(p).applyMatrix4(placed).sub(origin).dot(normal));
    }
    if (!Number.isFinite(low)) return this.editor.notice("select strokes first (V, then click or drag a box)");
    if (!this.translate(-low * normal.x, -low * normal.y, -low * normal.z, "drop")) this.editor.notice("already on the work plane");
  }

  /// Nudges the selection by (`dx`, `dy`) along the work plane's own x and y.
  nudge(dx, dy) {
    const m = matrixOf(this.view.workPlacement);
    const x = new THREE.Vector3().setFromMatrixColumn(m, 0).normalize();
    const y = new THREE.Vector3().setFromMatrixColumn(m, 1).normalize();
    const d = x.multiplyScalar(dx).addScaledVector(y, dy);
    this.translate(d.x, d.y, d.z);
  }

  /// Takes the selection back (Delete): one command, undone as one.
  remove() {
    if (!this.ids.size) return this.editor.notice("select strokes first (V, then click or drag a box)");
    if (this.own().length !== this.ids.size) return this.editor.notice("you can delete only your own strokes");
    const takeBack = this.editor.takeBack;
    const command = takeBack.strokesCommand(this.list, true);
    if (!command.redo()) return this.editor.notice("cannot delete: not connected to the proxy; try again");
    takeBack.push(command);
    this.clear();
  }
}

/// Whether two placements are the same, bit for bit (null: the identity).
function same(a, b) {
  const [x, y] = [a || IDENTITY, b || IDENTITY];
  return x.every((v, i) => Object.is(v, y[i]));
}

/// The distance from page point `p` to the segment `a`-`b` (each [x, y]).
function segmentDistance([px, py], [ax, ay], [bx, by]) {
  const [dx, dy] = [bx - ax, by - ay];
  const length2 = dx * dx + dy * dy;
  const t = length2 > 0 ? Math.max(0, Math.min(1, ((px - ax) * dx + (py - ay) * dy) / length2)) : 0;
  return Math.hypot(px - (ax + t * dx), py - (ay + t * dy));
}

/// The Select tool (V): click, shift-click and box select; drag the gizmo's handles.
export function selectTool() {
  let state = "idle"; // idle | pointing | boxing | dragging
  let start = null; // the sample where the pointer went down
  let travelled = 0; // the farthest it went from there (CSS px)
  let shift = false;
  let box = null; // the box's element on the page while boxing
  addEventListener("keydown", (e) => (shift = e.shiftKey));
  addEventListener("keyup", (e) => (shift = e.shiftKey));
  const showBox = (a, b) => {
    if (!box) {
      box = document.createElement("div");
      box.id = "select-box";
      box.style.cssText = "position:fixed;border:1px dashed #1d6fd6;background:#1d6fd622;pointer-events:none";
      document.body.append(box);
    }
    Object.assign(box.style, {
      left: `${Math.min(a.clientX, b.clientX)}px`,
      top: `${Math.min(a.clientY, b.clientY)}px`,
      width: `${Math.abs(b.clientX - a.clientX)}px`,
      height: `${Math.abs(b.clientY - a.clientY)}px`,
    });
  };
  const stop = (editor) => {
    if (state === "dragging") editor.selection.letGo();
    box?.remove();
    box = null;
    state = "idle";
  };
  return {
    id: "select",
    label: "Select",
    keys: ["v"],
    cursor: "default",
    get state() {
      return state;
    },
    onEnter() {},
    onExit(editor) {
      stop(editor);
      editor.selection.picking = null;
      editor.selection.clear();
    },
    down(editor, pointer, sample) {
      start = sample;
      travelled = 0;
      state = editor.selection.grab(sample.clientX, sample.clientY) ? "dragging" : "pointing";
    },
    move(editor, pointer, samples) {
      const s = samples[samples.length - 1];
      travelled = Math.max(travelled, Math.hypot(s.clientX - start.clientX, s.clientY - start.clientY));
      if (state === "dragging") return editor.selection.moveGrab(s.clientX, s.clientY);
      if (state === "pointing" && Math.hypot(s.clientX - start.clientX, s.clientY - start.clientY) >= BOX_SLOP_PX) state = "boxing";
      if (state === "boxing") showBox(start, s);
    },
    up(editor) {
      const selection = editor.selection;
      // A press on the gizmo that did not move is a click: it picks what is under it.
      if (state === "dragging" && travelled < BOX_SLOP_PX) {
        stop(editor);
        state = "pointing";
      }
      if (state === "pointing" && selection.picking) selection.pickPoint(start.clientX, start.clientY);
      else if (state === "pointing") {
        const id = selection.pick(start.clientX, start.clientY);
        selection.repeat = null; // a stroke picked by hand: the next duplicate is in place
        if (shift) selection.set(id === null ? selection.list : selection.ids.has(id) ? selection.list.filter((x) => x !== id) : [...selection.list, id]);
        else selection.set(id === null ? [] : [id]);
      } else if (state === "boxing" && box) {
        const r = box.getBoundingClientRect();
        const ids = selection.inBox(r.left, r.top, r.right, r.bottom);
        selection.set(shift ? [...new Set([...selection.list, ...ids])] : ids);
      }
      stop(editor);
    },
    interrupt(editor) {
      stop(editor);
    },
  };
}
