-- The append log (see proxy/src/store/log.rs): each group commit stores the appends it
-- acknowledges as one record here, keyed only by an increasing id, so a commit touches the end
-- of one B-tree instead of a page of the stroke_chunks index per batch. A stroke's samples are
-- moved into stroke_chunks when it ends (or has been in the log for a while); records no stroke
-- needs are deleted from the front. `writer` tells one writer's records from another's (each
-- replica start picks a new one). Rows written before this migration stay where they are:
-- readers read stroke_chunks and this table.
CREATE TABLE stroke_log (
    id          BIGSERIAL PRIMARY KEY,
    writer      BIGINT NOT NULL,
    data        BYTEA NOT NULL
);
-- The records are compact already: no compression attempt on each one.
ALTER TABLE stroke_log ALTER COLUMN data SET STORAGE EXTERNAL;
