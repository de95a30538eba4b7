// The modelling controls, wired to the work plane (workplane.js) and the selection
// (select.js): the work plane's menu (board, front, side, the selected stroke's plane, the
// plane through three points) and its moves along the normal, the gizmo's mode (move or turn),
// snapping, duplicate and mirror. Keys: [ and ] move the work plane (Shift: a grid cell), R
// turn, S snap, M mirror, Ctrl/Cmd+D duplicate (V, the Select tool, is tools.js's).
import { GRID_CELL, GRID_SNAP } from "./workplane.js";

const $ = (id) => document.getElementById(id);

export function attachModelBar(editor, { workPlane, selection }) {
  const plane = $("plane");
  const showPlane = () => {
    plane.value = workPlane.kind;
    plane.title = `the work plane the pen draws on (its grid)${workPlane.offset ? `, moved ${workPlane.offset} along its normal` : ""}`;
  };
  workPlane.onChange = showPlane;
  showPlane();
  const showTool = (tool) => document.body.classList.toggle("selecting", tool.id === "select");
  editor.on("tool", showTool);
  showTool(editor.tool);
  plane.onchange = () => {
    const kind = plane.value;
    plane.blur(); // the keys are the page's again
    if (kind === "stroke") {
      const [id] = selection.list;
      if (selection.ids.size !== 1) {
        editor.notice("select one stroke first (V, then click it): the work plane becomes its plane");
        return showPlane();
      }
      workPlane.set("stroke", editor.view.strokes.get(id).placement);
    } else if (kind === "points") {
      showPlane();
      selection.pickPlane();
    } else {
      workPlane.set(kind);
    }
    editor.notice(`drawing on the ${plane.options[plane.selectedIndex].text.toLowerCase()} plane`);
  };
  const move = (sign, big) => workPlane.move(sign * (big ? GRID_CELL : GRID_SNAP));
  $("plane-back").onclick = (e) => move(-1, e.shiftKey);
  $("plane-forth").onclick = (e) => move(1, e.shiftKey);

  const turn = $("turn");
  const setTurn = (on) => {
    turn.setAttribute("aria-pressed", String(on));
    selection.setMode(on ? "rotate" : "translate");
  };
  turn.onclick = () => setTurn(turn.getAttribute("aria-pressed") !== "true");
  const snap = $("snap");
  const toggleSnap = () => {
    selection.setSnap(!selection.snap);
    snap.setAttribute("aria-pressed", String(selection.snap));
  };
  snap.onclick = toggleSnap;
  $("duplicate").onclick = () => selection.duplicate();
  $("mirror").onclick = () => selection.mirror();

  addEventListener("keydown", (e) => {
    if (e.target instanceof HTMLInputElement || e.target instanceof HTMLSelectElement || document.querySelector("dialog[open]")) return;
    const key = e.key.toLowerCase();
    if (e.ctrlKey || e.metaKey) {
      if (key === "d") {
        e.preventDefault(); // not the browser's bookmark
        selection.duplicate();
      }
      return;
    }
    if (e.altKey) return;
    if (e.code === "BracketLeft") move(-1, e.shiftKey);
    else if (e.code === "BracketRight") move(1, e.shiftKey);
    else if (key === "r") setTurn(turn.getAttribute("aria-pressed") !== "true");
    else if (key === "s") toggleSnap();
    else if (key === "m") selection.mirror();
  });
}
