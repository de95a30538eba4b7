-- A participant has an identity of its own, derived from the session and the participant's key
-- (proxy/src/identity.rs; the key is never stored), and may be on several connections at once
-- (a reconnect that says hello before the old connection's end is noticed, or two windows).
-- So a row is one connection, keyed by `connection` (the old `id`, which was already one per
-- connection), and `participant` says who. Rows written before name their connection as the
-- participant, as they did.
ALTER TABLE participants RENAME COLUMN id TO connection;
ALTER TABLE participants ADD COLUMN participant TEXT NOT NULL DEFAULT '';
UPDATE participants SET participant = connection;
