-- Participants of a session: one row per WebSocket connection that said hello. A row whose
-- left_at is NULL is present.
CREATE TABLE participants (
    id          TEXT PRIMARY KEY,
    session_id  TEXT NOT NULL REFERENCES sessions (id),
    name        TEXT NOT NULL,
    joined_at   BIGINT NOT NULL,
    left_at     BIGINT
);
CREATE INDEX participants_by_session ON participants (session_id, joined_at);
