-- Samples are stored as the codec's compact point batch (about 2-6 bytes a sample) instead of
-- 32 bytes of f64. `layout` says which a row holds, so a database written before still reads:
-- 0 = little-endian f64 quadruples x, y, t, p (every row written before this migration),
-- 1 = penmesh::protocol::encode_point_batch. Only proxy/src/store reads or writes these blobs.
ALTER TABLE stroke_chunks ADD COLUMN layout SMALLINT NOT NULL DEFAULT 0;
ALTER TABLE simplified ADD COLUMN layout SMALLINT NOT NULL DEFAULT 0;
