// Undo and redo of our own strokes, and the eraser's removals, as one history: drawing a stroke
// or erasing one is a step; undo takes the last step back (a drawn stroke is taken back, an
// erased one brought back), redo does it again. Only our own strokes: the proxy refuses the
// others' (docs/web.md). The proxy's answers (`stroke_removed`, `stroke_restored`) change the
// view, not this history; a request that cannot be sent (no connection) leaves it unchanged.
// Moves and duplicates (select.js) are steps of the same history: a command with `undo()` and
// `redo()`, each returning whether it could be sent.

export class TakeBack {
  /// `send(stroke, remove)` asks the proxy to take back (`remove`) or bring back a stroke; it
  /// returns whether the request went out.
  constructor(send) {
    this.send = send;
    this.undone = []; // steps to take back: {stroke, remove}, `remove` being what undo asks
    this.redone = []; // steps undone, to do again
    this.onChange = () => {}; // either list changed
  }

  /// We drew `stroke` (it is done).
  drawn(stroke) {
    this.undone.push({ stroke, remove: true });
    this.redone.length = 0;
    this.onChange();
  }

  /// The eraser touched our `stroke`: it is taken back now, and undo brings it back.
  erase(stroke) {
    if (!this.send(stroke, true)) return false;
    this.undone.push({ stroke, remove: false });
    this.redone.length = 0;
    this.onChange();
    return true;
  }

  /// A command done (a move, a duplicate): undo calls its `undo`, redo its `redo`.
  done(command) {
    this.undone.push({ command });
    this.redone.length = 0;
    this.onChange();
  }

  undo() {
    return this.step(this.undone, this.redone);
  }

  redo() {
    return this.step(this.redone, this.undone);
  }

  /// Does the last step of `from` (its inverse goes on `to`); false when there is none or it
  /// cannot be sent.
  step(from, to) {
    const last = from[from.length - 1];
    if (last?.command) {
      if (!(from === this.undone ? last.command.undo() : last.command.redo())) return false;
      to.push(from.pop());
      this.onChange();
      return true;
    }
    if (!last || !this.send(last.stroke, last.remove)) return false;
    from.pop();
    to.push({ stroke: last.stroke, remove: !last.remove });
    this.onChange();
    return true;
  }
}
