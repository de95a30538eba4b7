// The selection panel's solid row (issue 51, docs/protocol.md "Solids"): what the selected
// strokes become, Line / Filled / Hole, and the depth, in px or in the print's mm (either typed;
// the mm at the print's scale, scene.js `mmPerUnit`, as the Export menu makes it). A change is
// sent over HTTP (`PUT /v1/strokes/{id}/solid`) for each of our selected strokes and is one
// command of the page's one history: undo sets each stroke's solid before it back, redo the one
// after. The proxy builds the new mesh before it stores the solid, so a solid a stroke cannot be
// (an open stroke filled) is refused with its words, shown to the person, and nothing changes;
// the stroke's new mesh comes with `peer_solid` and `peer_mesh` (session.js, scene.js
// `setSolid`, `replaceMesh`).

/// The depth (px) a stroke made Filled or Hole gets when it has none yet (the rod's).
export const DEFAULT_DEPTH_PX = 24;

const KINDS = [
  ["line", "Line", "the stroke's line (with a depth: a wall that tall)"],
  ["filled", "Filled", "the region the stroke encloses, as a plate that deep (a closed stroke only)"],
  ["hole", "Hole", "the region the stroke encloses, cut out of the solids under it"],
];

const THE_ROD = { kind: "line", depth: null };

/// Adds the solid row to `panel` (selpanel.js); `api` sets solids, `key()` is this tab's
/// participant key.
export function addSolidRow(panel, { api, key }) {
  const editor = panel.editor;
  const view = editor.view;
  const solidOf = (id) => view.strokes.get(id)?.solid || THE_ROD;
  const buttons = new Map();
  // Each stroke's latest request: the next waits for it. The proxy stores a solid, then its
  // mesh, in one request; two at once for one stroke (an undo right after a change) could
  // store the first's mesh last, so the mesh would not be the solid's.
  const inFlight = new Map(); // stroke -> Promise
  let depth;
  let depthMm;

  /// Sets each stroke of `solids` (id -> solid) to its solid; resolves to the ids set. A refusal
  /// is said in the proxy's words.
  async function send(solids) {
    const results = await Promise.allSettled(
      [...solids].map(([id, solid]) => {
        const request = (inFlight.get(id) || Promise.resolve()).catch(() => {}).then(() => api.setSolid(id, solid, key()));
        inFlight.set(id, request);
        return request;
      }),
    );
    const set = [];
    results.forEach((r, k) => {
      const [id, solid] = [...solids][k];
      if (r.status === "fulfilled") set.push(id);
      else editor.notice(`cannot make it ${solid.kind}: ${r.reason.detail || r.reason.message}`);
    });
    return set;
  }

  /// Our selected strokes become what `next(solid now)` says: one command for those the proxy
  /// took.
  async function change(next) {
    const selection = panel.selection;
    const mine = selection.own();
    if (mine.length < selection.list.length) editor.notice("only your own strokes change: the others' stay as they are");
    const before = new Map(mine.map((id) => [id, solidOf(id)]));
    const after = new Map(mine.map((id) => [id, next(solidOf(id))]));
    for (const id of mine) if (same(before.get(id), after.get(id))) [before, after].forEach((m) => m.delete(id));
    if (after.size === 0) return;
    const set = await send(after);
    if (set.length === 0) return panel.show();
    const pick = (m) => new Map(set.map((id) => [id, m.get(id)]));
    const [undone, redone] = [pick(before), pick(after)];
    // Sent over HTTP: the request always goes out; a refusal is said when it comes.
    editor.takeBack.push({ undo: () => (send(undone), true), redo: () => (send(redone), true) });
  }

  return {
    id: "solid",
    label: "solid",
    build(cells, p) {
      const group = document.createElement("span");
      group.className = "group";
      group.setAttribute("role", "radiogroup");
      group.setAttribute("aria-label", "solid");
      for (const [kind, text, title] of KINDS) {
        const b = document.createElement("button");
        b.id = `solid-${kind}`;
        b.textContent = text;
        b.title = title;
        b.setAttribute("aria-pressed", "false");
        b.onclick = () =>
          change((now) => ({
            kind,
            // A line keeps its depth (a wall) when it has one; a region needs one.
            depth: now.depth ?? (kind === "line" ? null : DEFAULT_DEPTH_PX),
          }));
        buttons.set(kind, b);
        group.append(b);
      }
      cells.append(group);
      const setDepth = (px) => {
        if (!(px > 0 && Number.isFinite(px))) return editor.notice("a depth is more than 0");
        change((now) => ({ kind: now.kind, depth: px }));
      };
      depth = p.numberField(cells, "solid-depth", setDepth);
      depth.input.title = "how deep (tall) the solid is, px of the drawing";
      cells.append(unit("px ·"));
      // A depth in mm is the px that make it at the print's scale now.
      depthMm = p.numberField(cells, "solid-depth-mm", (mm) => setDepth(mm / view.mmPerUnit()));
      depthMm.input.title = "how deep (tall) the solid is, mm of the print (at the Export menu's size)";
      cells.append(unit("mm"));
    },
    show(selection) {
      const solids = selection.list.map(solidOf);
      const first = solids[0] || THE_ROD;
      const alike = solids.every((s) => same(s, first));
      for (const [kind, b] of buttons) b.setAttribute("aria-pressed", String(alike && first.kind === kind));
      const known = alike && first.depth !== null;
      depth.show(known ? first.depth : "");
      depthMm.show(known ? first.depth * view.mmPerUnit() : "");
    },
  };
}

/// A unit beside a number field.
function unit(text) {
  const span = document.createElement("span");
  span.className = "mm";
  span.textContent = text;
  return span;
}

function same(a, b) {
  return a.kind === b.kind && a.depth === b.depth;
}
