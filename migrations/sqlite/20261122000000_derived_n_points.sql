-- A stroke's n_points is where its last stored chunk ends (see proxy/src/store): an append writes
-- its chunk and nothing else.
ALTER TABLE strokes DROP COLUMN n_points;
