-- penmesh schema (PostgreSQL). Timestamps are milliseconds since the Unix epoch; ids are UUID text.
-- Samples are stored as blobs private to proxy/src/store (little-endian f64 quadruples x, y, t, p).

CREATE TABLE sessions (
    id          TEXT PRIMARY KEY,
    token_hash  TEXT NOT NULL UNIQUE,   -- sha256 of the bearer token, lowercase hex
    created_at  BIGINT NOT NULL
);

CREATE TABLE strokes (
    id          TEXT PRIMARY KEY,
    session_id  TEXT NOT NULL REFERENCES sessions (id),
    participant TEXT NOT NULL,
    brush       TEXT NOT NULL,          -- JSON of penmesh::Brush
    params      TEXT NOT NULL,          -- JSON of penmesh::AcutsParams
    device      TEXT,
    status      TEXT NOT NULL CHECK (status IN ('open', 'done', 'interrupted')),
    n_points    BIGINT NOT NULL DEFAULT 0,
    n_retained  BIGINT NOT NULL DEFAULT 0,
    created_at  BIGINT NOT NULL,
    updated_at  BIGINT NOT NULL
);
CREATE INDEX strokes_by_session ON strokes (session_id, created_at);

-- The resampled samples as received, one row per accepted batch (seq = index of the first).
CREATE TABLE stroke_chunks (
    stroke_id   TEXT NOT NULL REFERENCES strokes (id),
    seq         BIGINT NOT NULL,
    n           BIGINT NOT NULL,
    data        BYTEA NOT NULL,
    PRIMARY KEY (stroke_id, seq)
);

-- The simplified stroke, written once when the stroke ends.
CREATE TABLE simplified (
    stroke_id   TEXT PRIMARY KEY REFERENCES strokes (id),
    indices     BYTEA NOT NULL,          -- little-endian u64 indices into the raw samples
    data        BYTEA NOT NULL
);

CREATE TABLE meshes (
    stroke_id   TEXT PRIMARY KEY REFERENCES strokes (id),
    glb         BYTEA NOT NULL,
    vertices    BIGINT NOT NULL,
    triangles   BIGINT NOT NULL,
    uploader    TEXT,
    created_at  BIGINT NOT NULL
);
