// The selection's panel: placing by numbers (TinkerCAD's dimensions, Blender's typed
// transforms). Shown while something is selected, it has a row per fact, each row a small
// object: `{ id, label, build(cells, panel), show(selection, panel) }`. `build` makes the row's
// inputs in `cells` once; `show` fills them whenever the selection, its placements or its modes
// change. Rows here:
//   position  x, y, z of the selection's box's low corner (session units, CSS px at one to
//             one; the print's mm beside): a typed value moves it there, one undoable step;
//   size      its box's sides, in px and the print's mm;
//   turn      a typed angle turns it about x, y or z through its centre, one undoable step.
// Another module adds its rows with `panel.addRow(row)` (after this one's, in order).
import * as THREE from "three";

const $ = (id) => document.getElementById(id);

const round = (v) => Math.round(v * 10) / 10;

export class SelectionPanel {
  constructor(editor, selection) {
    this.editor = editor;
    this.selection = selection;
    this.element = $("selection-panel");
    this.rows = [];
    editor.on("selection", () => this.show());
    for (const row of [positionRow(), sizeRow(), turnRow()]) this.addRow(row);
    this.show();
  }

  /// Adds `row` at the end of the panel.
  addRow(row) {
    const line = document.createElement("div");
    line.className = "row";
    line.id = `selection-${row.id}`;
    const label = document.createElement("span");
    label.className = "label";
    label.textContent = row.label;
    const cells = document.createElement("span");
    cells.className = "cells";
    line.append(label, cells);
    this.element.append(line);
    row.build(cells, this);
    this.rows.push(row);
    this.show();
  }

  /// The panel for the selection now: hidden when nothing is selected.
  show() {
    const on = this.selection.ids.size > 0;
    this.element.hidden = !on;
    if (!on) return;
    for (const row of this.rows) row.show(this.selection, this);
  }

  /// A number field: Enter (or leaving it changed) calls `commit(value)`; Escape puts the
  /// shown value back. Its `show(v)` leaves a field being typed in alone.
  numberField(cells, name, commit) {
    const input = document.createElement("input");
    input.type = "number";
    input.step = "any";
    input.id = `selection-${name}`;
    input.setAttribute("aria-label", name);
    let shown = "";
    const done = () => {
      const value = Number(input.value);
      if (input.value === "" || !Number.isFinite(value)) {
        input.value = shown;
        return;
      }
      if (input.value !== shown) commit(value);
    };
    input.onkeydown = (e) => {
      e.stopPropagation(); // the page's keys stay out of typing
      if (e.key === "Enter") {
        input.blur(); // its change commits
      } else if (e.key === "Escape") {
        input.value = shown;
        input.blur();
      }
    };
    input.onchange = done;
    cells.append(input);
    return {
      input,
      show(value) {
        shown = value === "" ? "" : String(round(value));
        if (document.activeElement !== input) input.value = shown;
      },
    };
  }
}

function positionRow() {
  let fields;
  let mm;
  return {
    id: "position",
    label: "position",
    build(cells, panel) {
      fields = ["x", "y", "z"].map((axis, k) =>
        panel.numberField(cells, `position-${axis}`, (value) => {
          const low = panel.selection.bounds().min.getComponent(k);
          const d = [0, 0, 0];
          d[k] = value - low;
          panel.selection.translate(...d);
        }),
      );
      mm = document.createElement("span");
      mm.className = "mm";
      cells.append(mm);
    },
    show(selection, panel) {
      const low = selection.bounds().min;
      fields.forEach((f, k) => f.show(low.getComponent(k)));
      const k = panel.editor.view.mmPerUnit();
      mm.textContent = `px · ${[low.x, low.y, low.z].map((v) => round(v * k)).join(", ")} mm`;
    },
  };
}

function sizeRow() {
  let text;
  return {
    id: "size",
    label: "size",
    build(cells) {
      text = document.createElement("span");
      cells.append(text);
    },
    show(selection, panel) {
      const size = selection.bounds().getSize(new THREE.Vector3());
      const k = panel.editor.view.mmPerUnit();
      const sides = [size.x, size.y, size.z];
      text.textContent = `${sides.map(round).join(" × ")} px · ${sides.map((v) => round(v * k)).join(" × ")} mm`;
    },
  };
}

function turnRow() {
  let fields;
  return {
    id: "turn",
    label: "turn by °",
    build(cells, panel) {
      fields = ["x", "y", "z"].map((axis) => {
        const f = panel.numberField(cells, `turn-${axis}`, (degrees) => {
          panel.selection.turn(axis, degrees);
          f.show(0);
        });
        f.input.title = `turn the selection about ${axis} through its centre (degrees)`;
        return f;
      });
    },
    show() {
      for (const f of fields) f.show(0);
    },
  };
}
