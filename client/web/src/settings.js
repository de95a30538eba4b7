// What a person chooses in the page: the brush (colour and size), kept with the tab's identity
// (sessionStorage, like the participant key: another tab is another person), and the display
// name, asked once and kept for every session (localStorage), editable at any time.

// The proxy's default brush; the size is the one setting offered besides the colour.
const DEFAULT_BRUSH = { size: 8, pressure_response: 0.5, min_radius: 0.25, color: null };
const BRUSH_KEY = "penmesh:brush";
const NAME_KEY = "penmesh:name";
// The proxy refuses a name over 200 characters or with a NUL byte (hello.name).
const MAX_NAME = 200;

export function cleanName(name) {
  return String(name).replace(/\0/g, "").trim().slice(0, MAX_NAME);
}

/// The saved name, or null when it was never asked.
export function savedName() {
  const name = localStorage.getItem(NAME_KEY);
  return name ? cleanName(name) : null;
}

export function saveName(name) {
  localStorage.setItem(NAME_KEY, cleanName(name));
}

/// The brush of this tab: the saved one, else the default.
export function savedBrush() {
  try {
    const saved = JSON.parse(sessionStorage.getItem(BRUSH_KEY) || "null");
    return { ...DEFAULT_BRUSH, ...(saved || {}) };
  } catch {
    return { ...DEFAULT_BRUSH };
  }
}

export function saveBrush(brush) {
  sessionStorage.setItem(BRUSH_KEY, JSON.stringify(brush));
}

/// `#rrggbb` of a colour number, and back.
export const hexOf = (colour) => `#${colour.toString(16).padStart(6, "0")}`;
export const colourOf = (hex) => parseInt(hex.slice(1), 16);

// Two people's colours closer than this (RGB distance, 0-441) are told apart badly.
export const MIN_COLOUR_DISTANCE = 80;

export function colourDistance(a, b) {
  const ch = (c, shift) => (c >> shift) & 0xff;
  return Math.hypot(ch(a, 16) - ch(b, 16), ch(a, 8) - ch(b, 8), ch(a, 0) - ch(b, 0));
}

/// A colour for a person who did not choose one: `preferred` (their default, which the others
/// expect) when it is far enough from every colour in `taken`, else the colour of `palette`
/// farthest from all of them.
export function colourApart(preferred, taken, palette) {
  const nearest = (c) => Math.min(Infinity, ...taken.map((t) => colourDistance(c, t)));
  if (nearest(preferred) >= MIN_COLOUR_DISTANCE) return preferred;
  return palette.reduce((best, c) => (nearest(c) > nearest(best) ? c : best), palette[0]);
}
