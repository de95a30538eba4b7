//! Sessions and their tokens (stored as a hash).

use sqlx::Row;
use uuid::Uuid;

use super::{Store, now_ms, parse_uuid};

/// sha256 of a token, lowercase hex: what the sessions table stores.
pub fn hash_token(token: &str) -> String {
    use sha2::Digest;
    hex::encode(sha2::Sha256::digest(token.as_bytes()))
}

impl Store {
    pub async fn create_session(&self, id: Uuid, token_hash: &str) -> anyhow::Result<()> {
        let mut conn = self.pool.acquire().await?;
        let mut tx = sqlx::Connection::begin_with(&mut *conn, self.begin_statement()).await?;
        sqlx::query("INSERT INTO sessions (id, token_hash, created_at) VALUES ($1, $2, $3)")
            .bind(id.to_string())
            .bind(token_hash)
            .bind(now_ms())
            .execute(&mut *tx)
            .await?;
        tx.commit().await?;
        Ok(())
    }

    /// The session a token belongs to.
    pub async fn session_for_token_hash(&self, token_hash: &str) -> anyhow::Result<Option<Uuid>> {
        let row = sqlx::query("SELECT id FROM sessions WHERE token_hash = $1")
            .bind(token_hash)
            .fetch_optional(&self.pool)
            .await?;
        row.map(|r| parse_uuid(&r.try_get::<String, _>("id")?)).transpose()
    }
}
