// The named views, one click or one key away (TinkerCAD's view cube, as buttons): Top (1),
// Front (2), Side (3) and a three-quarter view (4), each looking at the whole drawing from
// that side (camera.js VIEWS). The button of the view shown is pressed; an orbit, a pan or a
// zoom leaves it unpressed.
import { VIEWS } from "./camera.js";

const KEYS = { 1: "top", 2: "front", 3: "side", 4: "three" };

export function attachViews(editor) {
  const buttons = [...document.querySelectorAll("[data-view]")];
  const show = () => {
    const rig = editor.view.rig;
    for (const b of buttons) {
      const v = VIEWS[b.dataset.view];
      b.setAttribute("aria-pressed", String(Math.abs(rig.yaw - v.yaw) < 1e-9 && Math.abs(rig.pitch - v.pitch) < 1e-9));
    }
  };
  for (const b of buttons) b.onclick = () => editor.look(b.dataset.view);
  editor.on("camera", show);
  show();
  addEventListener("keydown", (e) => {
    if (e.ctrlKey || e.metaKey || e.altKey) return;
    if (e.target instanceof HTMLInputElement || e.target instanceof HTMLSelectElement || document.querySelector("dialog[open]")) return;
    if (KEYS[e.key]) editor.look(KEYS[e.key]);
  });
}
