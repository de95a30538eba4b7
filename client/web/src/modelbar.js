// The modelling controls, wired to the work plane (workplane.js) and the selection
// (select.js): the work plane's menu (board, front, side, the selected stroke's plane, the
// plane through three points) and its moves along the normal, the gizmo's mode (move or turn),
// snapping, duplicate and mirror. Keys: [ and ] move the work plane (Shift: a grid cell), R
// turn (one ring at a time: z, x, y, off), S snap, M mirror, Ctrl/Cmd+D duplicate (in place;
// again after a move: the move repeated), D drop onto the work plane, Delete or Backspace take
// the selection back, arrows nudge it (Shift: x10) (V, the Select tool, is tools.js's).
import * as THREE from "three";
import { GRID_CELL, GRID_SNAP } from "./workplane.js";

const $ = (id) => document.getElementById(id);
// An arrow key nudges the selection along the work plane's x and y (Shift: ten times as far).
const ARROWS = { ArrowLeft: [-1, 0], ArrowRight: [1, 0], ArrowUp: [0, -1], ArrowDown: [0, 1] };

export function attachModelBar(editor, { workPlane, selection }) {
  const plane = $("plane");
  const offset = $("plane-offset");
  const showPlane = () => {
    plane.value = workPlane.kind;
    plane.title = `the work plane the pen draws on (its grid)${workPlane.offset ? `, moved ${workPlane.offset} along its normal` : ""}`;
    if (document.activeElement !== offset) offset.value = String(Math.round(workPlane.offset * 10) / 10);
  };
  offset.onkeydown = (e) => {
    e.stopPropagation(); // typing, not the page's keys
    if (e.key === "Enter" || e.key === "Escape") offset.blur();
    if (e.key === "Escape") showPlane();
  };
  offset.onchange = () => {
    const v = Number(offset.value);
    if (offset.value !== "" && Number.isFinite(v)) workPlane.setOffset(v);
    showPlane();
  };
  // Where a named plane (Front, Side) goes through: the selection's centre, else the ground's
  // point the Plane tool was clicked on, else the model's centre, else what the camera looks at.
  const anchor = () => {
    const ground = workPlane.groundPoint;
    workPlane.groundPoint = null; // used once
    if (!selection.ids.size && ground) return new THREE.Vector3(ground.x, ground.y, 0);
    const box = selection.ids.size ? selection.bounds() : editor.view.drawingBox();
    return box.isEmpty() ? editor.view.rig.target.clone() : box.getCenter(box.min.clone());
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
      workPlane.set(kind, undefined, anchor());
    }
    editor.notice(`drawing on the ${plane.options[plane.selectedIndex].text.toLowerCase()} plane`);
  };
  // [ toward the camera, ] away from it.
  const move = (sign, big) => workPlane.moveAway(sign * (big ? GRID_CELL : GRID_SNAP));
  $("plane-back").onclick = (e) => move(-1, e.shiftKey);
  $("plane-forth").onclick = (e) => move(1, e.shiftKey);

  // Turn: off (the handles move), then one ring at a time: about z, x, y, then off again.
  const turn = $("turn");
  const TURNS = [null, "Z", "X", "Y"];
  let turnIndex = 0;
  const nextTurn = () => {
    turnIndex = (turnIndex + 1) % TURNS.length;
    const axis = TURNS[turnIndex];
    turn.setAttribute("aria-pressed", String(axis !== null));
    // The scene's Y is the session's y flipped: named by the session's axis.
    turn.textContent = axis ? `Turn ${axis.toLowerCase()}` : "Turn";
    selection.setMode(axis ? "rotate" : "translate", axis || "Z");
  };
  turn.onclick = nextTurn;
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
    else if (key === "r") nextTurn();
    else if (key === "s") toggleSnap();
    else if (key === "m") selection.mirror();
    else if (key === "d" && editor.tool.id === "select" && selection.ids.size) selection.dropToPlane();
    else if ((e.key === "Delete" || e.key === "Backspace") && selection.ids.size) {
      e.preventDefault();
      selection.remove();
    } else if (ARROWS[e.key] && selection.ids.size) {
      e.preventDefault(); // not the page's scroll
      const step = e.shiftKey ? 10 : 1;
      selection.nudge(ARROWS[e.key][0] * step, ARROWS[e.key][1] * step);
    }
  });
}
