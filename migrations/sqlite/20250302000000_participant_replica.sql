-- The replica a participant is connected to (PostgreSQL only; with SQLite there is one).
ALTER TABLE participants ADD COLUMN replica_key BIGINT;
