// The choice beside the brush of what a new stroke becomes (issue 51): Line (the rod, as
// always), Filled (a plate of the region it encloses: draw it closed) or Hole, sent with the
// stroke's begin (`stroke_begin.solid`, protocol.js) at solidrow.js's default depth; the
// selection's panel changes it afterwards. The editor reads `editor.drawSolid` at each pen-down.
import { DEFAULT_DEPTH_PX } from "./solidrow.js";

/// Wires `select` (Line / Filled / Hole) to what `editor`'s next strokes become.
export function attachDrawSolid(editor, select) {
  const choose = () => {
    const kind = select.value;
    editor.drawSolid = kind === "line" ? null : { kind, depth: DEFAULT_DEPTH_PX };
  };
  select.onchange = () => {
    choose();
    select.blur(); // the page's keys (tools, views) work again at once
  };
  select.onkeydown = (e) => e.stopPropagation(); // arrows choose here, not nudge the selection
  choose();
}
