-- A `simplified` row with `upto` set is not the simplified stroke: it holds what ACUTS retains
-- of the first `upto` samples of a stroke that is not done (no pen-up yet), written when a
-- session's history had to replay a long unfinished stroke, so that the next history reads it
-- instead of replaying the stroke again. The row of a done stroke has `upto` NULL: the stroke's
-- end replaces any such row, and such a row never replaces the end's.
ALTER TABLE simplified ADD COLUMN upto BIGINT;
