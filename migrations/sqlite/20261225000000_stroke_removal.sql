-- A stroke taken back (undo, or the eraser) is not deleted: its row is marked, with who took it
-- back and when (milliseconds since the Unix epoch), and every sample, the simplified stroke and
-- the mesh stay stored. A restore (redo) clears the mark. The session's history, its strokes
-- list and its mesh bundle leave a marked stroke out; its own reads keep working. Kept as long
-- as the session: nothing here is ever purged.
ALTER TABLE strokes ADD COLUMN removed_at BIGINT;
ALTER TABLE strokes ADD COLUMN removed_by TEXT;
