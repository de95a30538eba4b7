// The error of a frame or message that is not the protocol's, shared by the message codec
// (codec.js) and the point batch (pointbatch.js), and how a value is named in its words.

/// A frame or a message that is not the protocol's, with what is wrong.
export class FrameError extends Error {
  constructor(message) {
    super(message);
    this.name = "FrameError";
  }
}

/// A value as an error message names it.
export const describe = (v) => (v === null ? "null" : Array.isArray(v) ? "an array" : typeof v === "string" ? `the string ${JSON.stringify(v.slice(0, 40))}` : `${typeof v} ${String(v)}`);
