-- A stroke imported from a penmesh GLB (POST /v1/sessions/{id}/import, issue 39). Its drawer
-- (strokes.participant) is the participant who imported it: an import never acts as another
-- participant. This row keeps where it came from: its id in the file (source_stroke), its
-- author there (author_id, author_name), when it was drawn there (drawn_at, ms since the Unix
-- epoch), when it was imported (imported_at) and the name the importer gave (importer_name,
-- shown as the drawer's name where the importer never joined the session live).
CREATE TABLE stroke_imports (
    stroke_id     TEXT PRIMARY KEY REFERENCES strokes (id),
    source_stroke TEXT NOT NULL,
    author_id     TEXT NOT NULL,
    author_name   TEXT NOT NULL,
    drawn_at      BIGINT NOT NULL,
    imported_at   BIGINT NOT NULL,
    importer_name TEXT NOT NULL
);
