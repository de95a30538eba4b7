// The ink: our strokes drawn at once on a 2D canvas under the pen, never waiting for the
// network, each until its mesh replaces it (or it is taken back). Its points are kept on the
// work plane it was begun on (stroke coordinates, and that plane's placement) and drawn where
// the camera shows them, so the ink moves with a zoom, a pan or an orbit as its mesh will; its
// width is the mesh's (ribbon.js).
import { radiusOf } from "./ribbon.js";

export class Ink {
  /// `brush`: the brush our strokes are drawn with; `view`: the 3D view, which places plane
  /// points on the page (`toPage`) and says the scale (`pixelsPerUnit`).
  constructor(canvas, brush, view) {
    this.canvas = canvas;
    // Drawn on the CPU: with Chromium's GPU canvas (SwiftShader here) a stroke's ink stayed on
    // screen after the clear that removed it, in about half the runs of a browser test
    // (first-minutes.mjs 6), the same calls each time; a few lines a frame cost nothing there.
    this.ctx = canvas.getContext("2d", { willReadFrequently: true });
    this.paths = new Map(); // stroke -> {colour, placement, points: [[x, y, pressure]]}
    this.colour = "#333";
    this.brush = brush;
    this.view = view;
  }

  resize(width, height) {
    this.canvas.width = width * devicePixelRatio;
    this.canvas.height = height * devicePixelRatio;
    this.redraw();
  }

  setColour(css) {
    this.colour = css;
  }

  /// Strokes on the ink now (the browser tests check that none is left behind).
  get count() {
    return this.paths.size;
  }

  begin(stroke) {
    this.paths.set(stroke, { colour: this.colour, placement: this.view.workPlacement, points: [] });
  }

  /// A point of `stroke` on the drawing plane.
  add(stroke, x, y, pressure) {
    const path = this.paths.get(stroke);
    if (path) path.points.push([x, y, pressure]);
  }

  /// The stroke's mesh is on screen, or it was taken back: its ink goes.
  remove(stroke) {
    if (this.paths.delete(stroke)) this.redraw();
  }

  redraw() {
    // An empty overlay stays as it is: clearing it again on every camera move made the
    // compositor take the canvas anew each frame (the busy board's orbit, docs/performance-log.md).
    if (this.paths.size === 0 && this.blank) return;
    this.blank = this.paths.size === 0;
    const ctx = this.ctx;
    ctx.setTransform(devicePixelRatio, 0, 0, devicePixelRatio, 0, 0);
    ctx.clearRect(0, 0, this.canvas.width, this.canvas.height);
    ctx.lineCap = "round";
    const scale = this.view.pixelsPerUnit();
    for (const { colour, placement, points } of this.paths.values()) {
      ctx.strokeStyle = colour;
      let previous = null;
      for (const [x, y, p] of points) {
        const at = this.view.toPage(x, y, placement);
        ctx.lineWidth = Math.max(1, 2 * radiusOf(this.brush, p) * scale);
        ctx.beginPath();
        ctx.moveTo(...(previous || at));
        ctx.lineTo(...at);
        ctx.stroke();
        previous = at;
      }
    }
  }
}
