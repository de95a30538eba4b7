// The one input surface and its dispatcher: every pointer, wheel and key of the drawing area
// comes here first. The camera's gestures are taken out before any tool sees them, in every
// tool: the wheel zooms about the pointer; two fingers pinch (zoom and pan; the tool is
// interrupted, so a pinch never draws); space held, the middle button or the right button
// drags the view. What is left goes to the editor's active tool (tools.js); a pen's eraser end
// goes to the eraser whatever the tool. While a pen is down, touches are ignored (palm
// rejection). A 200-240 Hz pen delivers several samples per display frame: every one of them
// is taken (getCoalescedEvents).

// Mouse and touch report no real pressure: they draw with this one (docs/web.md).
export const CONSTANT_PRESSURE = 0.5;
/// The pen's eraser end (or a pen's eraser button held): Pointer Events report it as button
/// 5, `buttons & 32`.
export const ERASER_BUTTONS = 32;
// How much one wheel notch (deltaY 100) zooms.
const WHEEL_ZOOM = Math.log(1.2) / 100;

const pressureOf = (e) => (e.pointerType === "pen" ? Math.min(1, Math.max(0, e.pressure)) : CONSTANT_PRESSURE);

/// Routes `surface`'s input to `editor`.
export function attachInput(surface, editor) {
  const pointers = new Map(); // pointerId -> {x, y, type}
  let routed = null; // {pointerId, tool, type, t0}: the pointer a tool has
  let gesture = null; // {kind: "pan", pointerId} | {kind: "pinch", ids: [a, b], distance, centre}
  let penDown = false; // any pen on the page, for palm rejection
  let space = false; // the space bar held: drags pan

  addEventListener("pointerdown", (e) => {
    if (e.pointerType === "pen") penDown = true;
  }, true);
  addEventListener("pointerup", (e) => {
    if (e.pointerType === "pen") penDown = false;
  }, true);

  const sampleOf = (e) => ({ clientX: e.clientX, clientY: e.clientY, t: e.timeStamp - routed.t0, p: pressureOf(e) });
  const pinchOf = ([a, b]) => {
    const [p, q] = [pointers.get(a), pointers.get(b)];
    return { distance: Math.hypot(q.x - p.x, q.y - p.y), centre: [(p.x + q.x) / 2, (p.y + q.y) / 2] };
  };
  const interruptTool = () => {
    if (!routed) return;
    routed.tool.interrupt(editor);
    routed = null;
  };

  surface.addEventListener("pointerdown", (e) => {
    if (e.pointerType === "touch" && penDown) return; // palm rejection
    pointers.set(e.pointerId, { x: e.clientX, y: e.clientY, type: e.pointerType });
    try {
      surface.setPointerCapture(e.pointerId);
    } catch {
      // A pointer the browser does not know as active (an event made by a script): no capture.
    }
    const touches = [...pointers].filter(([, p]) => p.type === "touch").map(([id]) => id);
    if (e.pointerType === "touch" && touches.length >= 2) {
      interruptTool();
      const ids = touches.slice(-2);
      gesture = { kind: "pinch", ids, ...pinchOf(ids) };
      return;
    }
    if (gesture || routed) return;
    if (space || e.button === 1 || e.button === 2) {
      gesture = { kind: "pan", pointerId: e.pointerId };
      surface.style.cursor = "grabbing";
      return;
    }
    if (e.pointerType === "mouse" && e.button !== 0) return;
    const tool = (e.buttons & ERASER_BUTTONS) !== 0 ? editor.tools.erase : editor.tool;
    routed = { pointerId: e.pointerId, tool, type: e.pointerType, t0: e.timeStamp };
    tool.down(editor, { type: e.pointerType }, sampleOf(e));
  });

  surface.addEventListener("pointermove", (e) => {
    const pointer = pointers.get(e.pointerId);
    if (!pointer) return;
    const from = [pointer.x, pointer.y];
    pointer.x = e.clientX;
    pointer.y = e.clientY;
    if (gesture?.kind === "pinch" && gesture.ids.includes(e.pointerId)) {
      const now = pinchOf(gesture.ids);
      if (gesture.distance > 0 && now.distance > 0) editor.zoomAt(...gesture.centre, now.distance / gesture.distance);
      editor.panBy(gesture.centre, now.centre);
      Object.assign(gesture, now);
    } else if (gesture?.kind === "pan" && gesture.pointerId === e.pointerId) {
      editor.panBy(from, [e.clientX, e.clientY]);
    } else if (routed && routed.pointerId === e.pointerId) {
      const events = e.getCoalescedEvents ? e.getCoalescedEvents() : [];
      routed.tool.move(editor, { type: e.pointerType }, (events.length ? events : [e]).map(sampleOf));
    }
  });

  const lift = (e) => {
    if (!pointers.delete(e.pointerId)) return;
    if (routed && routed.pointerId === e.pointerId) {
      const { tool, type } = routed;
      routed = null;
      tool.up(editor, { type });
    }
    if (gesture && (gesture.pointerId === e.pointerId || gesture.ids?.includes(e.pointerId))) {
      gesture = null;
      surface.style.cursor = "";
    }
  };
  surface.addEventListener("pointerup", lift);
  surface.addEventListener("pointercancel", lift);
  surface.addEventListener("contextmenu", (e) => e.preventDefault());

  surface.addEventListener("wheel", (e) => {
    e.preventDefault();
    // A trackpad's pinch comes as a wheel with ctrlKey and small deltas; a mouse wheel's notch
    // as about 100.
    const delta = e.deltaMode === 1 ? e.deltaY * 33 : e.deltaY;
    editor.zoomAt(e.clientX, e.clientY, Math.exp(-delta * WHEEL_ZOOM * (e.ctrlKey ? 5 : 1)));
  }, { passive: false });

  addEventListener("keydown", (e) => {
    if (e.code === "Space" && !(e.target instanceof HTMLInputElement) && !(e.target instanceof HTMLButtonElement)) {
      e.preventDefault();
      if (!space) {
        space = true;
        surface.style.cursor = "grab";
      }
    }
  });
  addEventListener("keyup", (e) => {
    if (e.code === "Space") {
      space = false;
      if (!gesture) surface.style.cursor = "";
    }
  });
  addEventListener("blur", () => {
    space = false;
  });
}
