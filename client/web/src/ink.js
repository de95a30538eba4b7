// The ink: our strokes drawn at once on a 2D canvas under the pen, in page pixels, never
// waiting for the network, each until its mesh replaces it.

export class Ink {
  /// `brush`: the brush our strokes are drawn with, for the ink's width.
  constructor(canvas, brush) {
    this.canvas = canvas;
    this.ctx = canvas.getContext("2d");
    this.paths = new Map(); // stroke -> [[clientX, clientY, pressure]]
    this.colour = "#333";
    this.brush = brush;
    this.scale = 1; // CSS pixels per unit of the drawing plane in the front view
  }

  resize(width, height) {
    this.canvas.width = width * devicePixelRatio;
    this.canvas.height = height * devicePixelRatio;
    this.redraw();
  }

  /// The ink is as wide as the mesh will be at this many CSS pixels per unit.
  setScale(pixelsPerUnit) {
    this.scale = pixelsPerUnit;
    this.redraw();
  }

  setColour(css) {
    this.colour = css;
  }

  begin(stroke) {
    this.paths.set(stroke, []);
  }

  add(stroke, clientX, clientY, pressure) {
    const path = this.paths.get(stroke);
    if (path) path.push([clientX, clientY, pressure]);
  }

  /// The stroke's mesh is on screen: its ink goes.
  remove(stroke) {
    if (this.paths.delete(stroke)) this.redraw();
  }

  redraw() {
    const ctx = this.ctx;
    ctx.setTransform(devicePixelRatio, 0, 0, devicePixelRatio, 0, 0);
    ctx.clearRect(0, 0, this.canvas.width, this.canvas.height);
    ctx.lineCap = "round";
    ctx.strokeStyle = this.colour;
    for (const path of this.paths.values()) {
      for (let i = 0; i < path.length; i++) {
        const [x, y, p] = path[i];
        const [px, py] = path[Math.max(0, i - 1)];
        ctx.lineWidth = Math.max(0.5, 2 * this.brush.size * this.brush.pressure_response * p * this.scale);
        ctx.beginPath();
        ctx.moveTo(px, py);
        ctx.lineTo(x, y);
        ctx.stroke();
      }
    }
  }
}
