-- Records of the append log whose entries cannot be moved into stroke_chunks (a stroke with no
-- row, samples that do not decode or do not fit together): a copy of each, set aside for an
-- operator instead of failing the move for ever (proxy/src/store/log.rs, `set_aside`); the
-- record itself then leaves stroke_log as usual. `stroke_id` is the stroke whose entries could
-- not be moved, '' for a record that does not decode at all.
CREATE TABLE stroke_log_set_aside (
    record_id    BIGINT NOT NULL,
    stroke_id    TEXT NOT NULL,
    writer       BIGINT NOT NULL,
    data         BYTEA NOT NULL,
    reason       TEXT NOT NULL,
    set_aside_at BIGINT NOT NULL,
    PRIMARY KEY (record_id, stroke_id)
);
