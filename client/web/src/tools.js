// The tools: one active at a time (editor.js `setTool`), each a small state object. A tool
// gets the pointer the dispatcher (input.js) routes to it, after the camera's gestures (wheel,
// pinch, space-drag, middle or right drag) were taken out:
//   onEnter(editor) / onExit(editor)   it becomes active / stops being (a drag in progress ends)
//   down(editor, pointer, sample)      a pointer goes down; `pointer.type` is pen, mouse or touch
//   move(editor, pointer, samples)     it moved (every coalesced sample)
//   up(editor, pointer)                it lifted
//   interrupt(editor)                  a second finger landed: the gesture is the camera's now
// plus `id`, `label`, `keys` (its shortcuts) and `cursor`. Adding a tool is adding one here
// (Select, V, is select.js's).
// A sample is {clientX, clientY, t, p}, `t` in ms since the pointer went down.

import { selectTool } from "./select.js";

// A finger moves this far (CSS px) before it draws: until then a second finger makes it a
// pinch, and nothing is drawn.
export const TOUCH_SLOP_PX = 8;

// The eraser's cursor: a ring as wide as it erases (editor.js ERASER_RADIUS_PX).
const ERASER_CURSOR = `url("data:image/svg+xml,${encodeURIComponent(
  '<svg xmlns="http://www.w3.org/2000/svg" width="20" height="20"><circle cx="10" cy="10" r="8" fill="#fff8" stroke="#333" stroke-width="1.5"/></svg>',
)}") 10 10, cell`;

/// Draw: pen, mouse or finger. A pen or a mouse draws at once; a finger waits in "pointing"
/// until it has moved TOUCH_SLOP_PX (a second finger before then draws nothing).
function drawTool() {
  let state = "idle"; // idle | pointing | drawing
  let held = []; // the samples of a finger still pointing
  const start = (editor, pointer, samples) => {
    state = editor.beginStroke(`web:${pointer.type}`, samples) ? "drawing" : "idle";
  };
  const stop = (editor) => {
    if (state === "drawing") editor.endStroke();
    state = "idle";
    held = [];
  };
  return {
    id: "draw",
    label: "Draw",
    keys: ["d", "p"],
    cursor: "crosshair",
    get state() {
      return state;
    },
    onEnter() {},
    onExit: stop,
    down(editor, pointer, sample) {
      if (pointer.type !== "touch") return start(editor, pointer, [sample]);
      state = "pointing";
      held = [sample];
    },
    move(editor, pointer, samples) {
      if (state === "drawing") return editor.strokeSamples(samples);
      if (state !== "pointing") return;
      held.push(...samples);
      const [a, b] = [held[0], held[held.length - 1]];
      if (Math.hypot(b.clientX - a.clientX, b.clientY - a.clientY) >= TOUCH_SLOP_PX) start(editor, pointer, held.splice(0));
    },
    up(editor, pointer) {
      // A finger's tap is a dot.
      if (state === "pointing") start(editor, pointer, held.splice(0));
      stop(editor);
    },
    interrupt(editor) {
      stop(editor);
    },
  };
}

/// Erase: every stroke of ours the pointer passes over is taken back (undo brings it back).
function eraseTool() {
  let drag = null; // {others: participants whose strokes it touched, command: its history's (takeback.js)}
  return {
    id: "erase",
    label: "Erase",
    keys: ["e"],
    cursor: ERASER_CURSOR,
    onEnter() {},
    onExit() {
      drag = null;
    },
    down(editor, pointer, sample) {
      drag = { others: new Set(), command: null };
      editor.eraseAt(sample.clientX, sample.clientY, drag);
    },
    move(editor, pointer, samples) {
      if (drag) for (const s of samples) editor.eraseAt(s.clientX, s.clientY, drag);
    },
    up() {
      drag = null;
    },
    interrupt() {
      drag = null;
    },
  };
}

/// Orbit: a drag turns the camera about what it looks at.
function orbitTool() {
  let last = null; // [x, y] of the dragging pointer
  return {
    id: "orbit",
    label: "Orbit",
    keys: ["o"],
    cursor: "grab",
    onEnter() {},
    onExit() {
      last = null;
    },
    down(editor, pointer, sample) {
      last = [sample.clientX, sample.clientY];
    },
    move(editor, pointer, samples) {
      if (!last) return;
      const s = samples[samples.length - 1];
      editor.orbitBy(s.clientX - last[0], s.clientY - last[1]);
      last = [s.clientX, s.clientY];
    },
    up() {
      last = null;
    },
    interrupt() {
      last = null;
    },
  };
}

/// Work plane (W, TinkerCAD's workplane tool): a click on a stroke puts the work plane on that
/// stroke's plane, a click on the ground puts it back on the board there (a Front or Side plane
/// picked next goes through that point); then the pen draws again.
function planeTool() {
  let start = null;
  return {
    id: "plane",
    label: "Plane",
    keys: ["w"],
    cursor: "copy",
    onEnter(editor) {
      editor.notice("click a stroke to draw on its plane, or the ground to draw on the board");
    },
    onExit() {
      start = null;
    },
    down(editor, pointer, sample) {
      start = sample;
    },
    move() {},
    up(editor) {
      if (start) editor.pickWorkPlane(start.clientX, start.clientY);
      start = null;
    },
    interrupt() {
      start = null;
    },
  };
}

/// A fresh set of the tools, by id, in the toolbar's order.
export function createTools() {
  return { draw: drawTool(), select: selectTool(), erase: eraseTool(), orbit: orbitTool(), plane: planeTool() };
}
