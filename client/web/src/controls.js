// The toolbar and the keys, wired to the editor (editor.js): they call its methods and show
// what its signals say (the active tool pressed and its cursor, undo and redo greyed out when
// there is nothing to take back, a notice for an action that did nothing). Shortcuts: each
// tool's keys (D draw, unless strokes are selected: then it drops them, modelbar.js; E erase,
// O orbit), Esc back to drawing, F fit, Ctrl+Z / Ctrl+Shift+Z /
// Ctrl+Y. Also the brush, the name, the link to share, a new session (asked first).
import { newSession } from "./landing.js";
import { colourOf, strokeColour } from "./scene.js";
import { cleanName, colourOf as colourNumber, hexOf, saveBrush, saveName } from "./settings.js";

// How long a notice stays (ms).
const NOTICE_MS = 3500;
const $ = (id) => document.getElementById(id);

/// Wires the page's controls to `editor`. Returns {name, showBrush, onBrush, onRename}: the
/// session sets the last two.
export function attachControls(editor, { session, name, askName, fail }) {
  const { brush } = editor;
  const controls = { name, onBrush: () => {}, onRename: () => {}, showBrush };

  // --- the tools: one group, one pressed ------------------------------------------------------
  const toolButtons = [...document.querySelectorAll("[data-tool]")];
  function showTool(tool) {
    for (const b of toolButtons) b.setAttribute("aria-pressed", String(b.dataset.tool === tool.id));
    $("stage").style.cursor = tool.cursor;
  }
  for (const b of toolButtons) b.onclick = () => editor.setTool(b.dataset.tool);
  editor.on("tool", showTool);
  showTool(editor.tool);

  // --- undo and redo ----------------------------------------------------------------------------
  function showHistory() {
    $("undo").disabled = !editor.canUndo;
    $("redo").disabled = !editor.canRedo;
  }
  editor.on("history", showHistory);
  showHistory();
  $("undo").onclick = () => editor.undo();
  $("redo").onclick = () => editor.redo();

  // --- notices ----------------------------------------------------------------------------------
  let noticeTimer = null;
  editor.on("notice", (text) => {
    $("notice").textContent = text;
    $("notice").classList.add("shown");
    clearTimeout(noticeTimer);
    noticeTimer = setTimeout(() => $("notice").classList.remove("shown"), NOTICE_MS);
  });

  // --- keys -------------------------------------------------------------------------------------
  addEventListener("keydown", (e) => {
    if (e.target instanceof HTMLInputElement || document.querySelector("dialog[open]")) return;
    const key = e.key.toLowerCase();
    if (e.ctrlKey || e.metaKey) {
      if (key === "z" || key === "y") {
        e.preventDefault();
        if (key === "y" || e.shiftKey) editor.redo();
        else editor.undo();
      }
      return;
    }
    if (e.altKey) return;
    if (key === "escape") return editor.setTool("draw");
    if (key === "f") return editor.fit();
    // With strokes selected, D drops them onto the work plane (TinkerCAD's D; modelbar.js).
    if (key === "d" && editor.tool.id === "select" && editor.selection.ids.size) return;
    const tool = Object.values(editor.tools).find((t) => t.keys.includes(key));
    if (tool) editor.setTool(tool.id);
  });

  // --- the brush --------------------------------------------------------------------------------
  function showBrush() {
    const me = editor.conn.me || "";
    const colour = brush.color === null ? colourOf(me) : strokeColour(me, brush);
    $("colour").value = `#${colour.getHexString()}`;
    $("size").value = String(brush.size);
    editor.ink.setColour(`#${colour.getHexString()}`);
    controls.onBrush();
  }
  $("colour").oninput = (e) => {
    brush.color = colourNumber(e.target.value);
    saveBrush(brush);
    editor.ink.setColour(hexOf(brush.color));
    controls.onBrush();
  };
  $("size").oninput = (e) => {
    brush.size = Number(e.target.value);
    saveBrush(brush);
  };

  // --- the name: a click selects it all, so typing replaces it; Enter sends it ----------------
  const nameBox = $("name");
  nameBox.value = name;
  if (askName) {
    nameBox.classList.add("ask");
    nameBox.placeholder = "your name";
  }
  nameBox.onfocus = () => nameBox.select();
  // A click would place the caret after focus selected the text: keep the selection.
  nameBox.onmouseup = (e) => {
    if (nameBox.dataset.selected !== "1") {
      e.preventDefault();
      nameBox.dataset.selected = "1";
    }
  };
  nameBox.onblur = () => delete nameBox.dataset.selected;
  nameBox.onkeydown = (e) => {
    if (e.key === "Enter") nameBox.blur();
    if (e.key === "Escape") {
      nameBox.value = controls.name;
      nameBox.blur();
    }
  };
  nameBox.onchange = () => {
    const cleaned = cleanName(nameBox.value);
    if (!cleaned) {
      nameBox.value = controls.name;
      return;
    }
    controls.name = cleaned;
    saveName(cleaned);
    nameBox.classList.remove("ask");
    controls.onRename(cleaned);
    editor.notice(`you are “${cleaned}” to the others now`);
  };

  // --- the menu (a phone's second row) --------------------------------------------------------
  $("toggle-more").onclick = () => {
    const open = document.body.classList.toggle("more");
    $("toggle-more").setAttribute("aria-expanded", String(open));
  };

  // --- sharing, a new session, the camera (the Export menu: export.js) ---------------------------------------------
  $("copy-link").onclick = async () => {
    try {
      await navigator.clipboard.writeText(location.href);
      editor.notice("link copied: whoever opens it can draw here");
    } catch {
      // No clipboard (an insecure origin, or refused): the link to copy by hand.
      prompt("Copy this link to share the session:", location.href);
    }
  };
  $("new").onclick = () => $("confirm-new").showModal();
  $("confirm-new-cancel").onclick = () => $("confirm-new").close();
  $("confirm-new-ok").onclick = () => {
    $("confirm-new").close();
    newSession(fail);
  };
  $("fit").onclick = () => editor.fit();
  return controls;
}
