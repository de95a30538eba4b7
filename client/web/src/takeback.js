// Undo and redo of our own strokes as one history of commands: drawing a stroke is one, and
// so is one drag of the eraser, however many strokes it erased (style.md). Undo takes the last
// command back (a drawn stroke is taken back, erased ones brought back), redo does it again.
// A command is `{undo(), redo()}`, each returning whether its requests went out, so other kinds
// (a move, a group) fit the same history. Only our own strokes: the proxy refuses the others'
// (docs/web.md). The proxy's answers (`stroke_removed`, `stroke_restored`) change the view, not
// this history; a request that cannot be sent (no connection) leaves it unchanged.

export class TakeBack {
  /// `send(stroke, remove)` asks the proxy to take back (`remove`) or bring back a stroke; it
  /// returns whether the request went out.
  constructor(send) {
    this.send = send;
    this.undone = []; // commands to undo, the last done last
    this.redone = []; // commands undone, to do again
    this.onChange = () => {}; // either list changed
  }

  /// A command just done: undo takes it back; what was undone cannot be redone any more.
  push(command) {
    this.undone.push(command);
    this.redone.length = 0;
    this.onChange();
  }

  /// The command that took back (`remove`) or brought back `strokes` (an array it may still
  /// grow): redo does the same again, undo the opposite.
  strokesCommand(strokes, remove) {
    const all = (r) => strokes.every((stroke) => this.send(stroke, r));
    return { strokes, undo: () => all(!remove), redo: () => all(remove) };
  }

  /// We drew `stroke` (it is done).
  drawn(stroke) {
    this.push(this.strokesCommand([stroke], false));
  }

  /// The eraser touched our `stroke`: it is taken back now. Every stroke one eraser `drag` (an
  /// object per drag) takes back joins that drag's command, while it is the last one.
  erase(stroke, drag) {
    const open = drag.command && this.undone[this.undone.length - 1] === drag.command;
    // Until the proxy's answer hides it, the drag may pass over a stroke it erased again.
    if (open && drag.command.strokes.includes(stroke)) return true;
    if (!this.send(stroke, true)) return false;
    if (open) {
      drag.command.strokes.push(stroke);
    } else {
      drag.command = this.strokesCommand([stroke], true);
      this.push(drag.command);
    }
    return true;
  }

  undo() {
    return this.step(this.undone, this.redone, "undo");
  }

  redo() {
    return this.step(this.redone, this.undone, "redo");
  }

  /// Undoes or redoes (`how`) the last command of `from`, which then goes on `to`; false when
  /// there is none or it cannot be sent.
  step(from, to, how) {
    const last = from[from.length - 1];
    if (!last || !last[how]()) return false;
    from.pop();
    to.push(last);
    this.onChange();
    return true;
  }
}
