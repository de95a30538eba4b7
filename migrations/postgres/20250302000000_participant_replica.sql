-- The replica a participant is connected to, as the key of the advisory lock that replica holds
-- while it lives: a participant whose replica's lock is gone (the replica died) has left.
ALTER TABLE participants ADD COLUMN replica_key BIGINT;
