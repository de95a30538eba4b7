// The pen: Pointer Events on one element in, samples out. A pen, a mouse or a finger draws;
// while a pen is down, touches are ignored (palm rejection). A 200-240 Hz pen delivers several
// samples per display frame: every one of them is taken (getCoalescedEvents).

// Mouse and touch report no real pressure: they draw with this one (docs/web.md).
export const CONSTANT_PRESSURE = 0.5;

const pressureOf = (e) => (e.pointerType === "pen" ? Math.min(1, Math.max(0, e.pressure)) : CONSTANT_PRESSURE);

/// The pen's eraser end (or a pen's eraser button held): Pointer Events report it as button
/// 5, `buttons & 32`.
export const ERASER_BUTTONS = 32;

/// Listens on `element`. `canStart()` says whether a stroke may begin; `down(device, sample)`
/// begins one (`device` is `web:pen`, `web:mouse` or `web:touch`); `move(samples)` gets the
/// samples of one pointer event; `up()` ends the stroke. A sample is `{clientX, clientY, t, p}`,
/// `t` in ms since pen-down. A pointer that goes down erasing (the pen's eraser end, or
/// `eraserTool()` for a mouse or a finger) draws nothing: `erase(clientX, clientY)` gets every
/// point it passes instead.
export function attachPen(element, { canStart, down, move, up, eraserTool, erase }) {
  let drawing = null; // {pointerId, t0, erasing}
  let penDown = false; // any pen on the page, for palm rejection

  addEventListener("pointerdown", (e) => {
    if (e.pointerType === "pen") penDown = true;
  }, true);
  addEventListener("pointerup", (e) => {
    if (e.pointerType === "pen") penDown = false;
  }, true);

  const sampleOf = (e) => ({ clientX: e.clientX, clientY: e.clientY, t: e.timeStamp - drawing.t0, p: pressureOf(e) });

  element.addEventListener("pointerdown", (e) => {
    if (drawing) return;
    if (e.pointerType === "touch" && penDown) return; // palm rejection
    const erasing = (e.buttons & ERASER_BUTTONS) !== 0 || eraserTool();
    if (e.pointerType === "mouse" && e.button !== 0) return;
    if (!erasing && !canStart()) return;
    try {
      element.setPointerCapture(e.pointerId);
    } catch {
      // A pointer the browser does not know as active (an event made by a script): no capture.
    }
    drawing = { pointerId: e.pointerId, t0: e.timeStamp, erasing };
    if (erasing) erase(e.clientX, e.clientY);
    else down(`web:${e.pointerType}`, sampleOf(e));
  });

  element.addEventListener("pointermove", (e) => {
    if (!drawing || e.pointerId !== drawing.pointerId) return;
    const events = e.getCoalescedEvents ? e.getCoalescedEvents() : [];
    if (drawing.erasing) for (const c of events.length ? events : [e]) erase(c.clientX, c.clientY);
    else move((events.length ? events : [e]).map(sampleOf));
  });

  const lift = (e) => {
    if (!drawing || e.pointerId !== drawing.pointerId) return;
    const erasing = drawing.erasing;
    drawing = null;
    if (!erasing) up();
  };
  element.addEventListener("pointerup", lift);
  element.addEventListener("pointercancel", lift);
}
