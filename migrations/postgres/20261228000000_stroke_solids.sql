-- What a stroke becomes (issue 51): its solids, as events, beside its placements. Nothing is
-- overwritten: each change is a new row with who set it and when (milliseconds since the Unix
-- epoch), so undo restores the one before exactly and every earlier one stays readable. The
-- current solid is the stroke's row of the highest id; a stroke with no row (every stroke
-- stored before, every stroke of a client of protocol 5 or 4) is the default, a line with no
-- depth (the pressure-width rod). solid: 9 bytes, the kind (0 line, 1 filled, 2 hole) then the
-- depth in px as a little-endian f64 (NaN for none), bit-exact (penmesh::Solid::to_bytes).
-- cause: 'begin' (its stroke_begin), 'set' (changed, or an undo), 'duplicate' or 'import'.
-- Kept as long as the session.
CREATE TABLE stroke_solids (
    id          BIGSERIAL PRIMARY KEY,
    stroke_id   TEXT NOT NULL REFERENCES strokes (id),
    solid       BYTEA NOT NULL,
    set_by      TEXT NOT NULL,
    set_at      BIGINT NOT NULL,
    cause       TEXT NOT NULL CHECK (cause IN ('begin', 'set', 'duplicate', 'import'))
);
CREATE INDEX stroke_solids_by_stroke ON stroke_solids (stroke_id, id);
