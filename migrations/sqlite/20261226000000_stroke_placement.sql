-- Where a stroke's plane stands in the session's 3D space (protocol version 5): its
-- placements, as events. Nothing is overwritten: each change is a new row with who set it and
-- when (milliseconds since the Unix epoch), so undo restores the one before exactly and every
-- earlier one stays readable. The current placement is the stroke's row of the highest id; a
-- stroke with no row (every stroke stored before, every stroke of a version-4 client) is at
-- the identity. matrix: the glTF node.matrix, 16 little-endian f64, column-major (128 bytes,
-- bit-exact). cause: 'begin' (the work plane of its stroke_begin), 'set' (moved, turned,
-- scaled, mirrored, an undo) or 'duplicate'. Kept as long as the session.
CREATE TABLE stroke_placements (
    id          INTEGER PRIMARY KEY,
    stroke_id   TEXT NOT NULL REFERENCES strokes (id),
    matrix      BLOB NOT NULL,
    set_by      TEXT NOT NULL,
    set_at      BIGINT NOT NULL,
    cause       TEXT NOT NULL CHECK (cause IN ('begin', 'set', 'duplicate'))
);
CREATE INDEX stroke_placements_by_stroke ON stroke_placements (stroke_id, id);
-- A duplicate (POST /v1/strokes/{id}/duplicate) is a stroke of its own (its pen data stored
-- again, its drawer the participant who duplicated) that records its source, and shares its
-- mesh: mesh_of names the stroke whose meshes row it shows (the source's, or the source's own
-- mesh_of), so a mesh is never copied.
ALTER TABLE strokes ADD COLUMN duplicate_of TEXT;
ALTER TABLE strokes ADD COLUMN mesh_of TEXT;
