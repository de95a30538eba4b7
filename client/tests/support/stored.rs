//! What a test reads back from a proxy's SQLite file, bypassing the proxy: each stroke's row,
//! its stored samples (decoded through the store's own layouts) and its mesh. Shared by the
//! client's tests and the lab's (`#[path]`), which both run a proxy on such a file.

use std::path::Path;

use penmesh::Sample;
use sqlx::Row;

/// One stroke as the database holds it.
#[derive(Debug, Clone)]
pub struct StoredStroke {
    pub id: String,
    pub session: String,
    pub status: String,
    pub n_points: u64,
    pub n_retained: u64,
    /// The raw (resampled) samples, from the stored chunks in seq order.
    pub raw: Vec<Sample>,
    /// `(seq, n)` of each stored chunk.
    pub chunks: Vec<(u64, u64)>,
    /// `(glb length, vertices, triangles)` of the stored mesh.
    pub mesh: Option<(u64, u64, u64)>,
    pub glb: Option<Vec<u8>>,
}

/// Every stroke of the database, oldest first.
pub async fn stored_strokes(db: &Path) -> Vec<StoredStroke> {
    let url = format!("sqlite://{}?mode=ro", db.display());
    let pool = sqlx::SqlitePool::connect(&url).await.expect("open the database");
    let rows = sqlx::query(
        "SELECT id, session_id, status, n_retained FROM strokes ORDER BY created_at, id",
    )
    .fetch_all(&pool)
    .await
    .unwrap();
    let mut strokes = Vec::new();
    for row in rows {
        let id: String = row.get("id");
        let chunks = sqlx::query(
            "SELECT seq, n, layout, data FROM stroke_chunks WHERE stroke_id = ? ORDER BY seq",
        )
        .bind(&id)
        .fetch_all(&pool)
        .await
        .unwrap();
        let mut raw = Vec::new();
        let mut spans = Vec::new();
        for chunk in chunks {
            let data: Vec<u8> = chunk.get("data");
            spans.push((chunk.get::<i64, _>("seq") as u64, chunk.get::<i64, _>("n") as u64));
            // The layout is the store's to know: decode through it.
            let layout: i64 = chunk.get("layout");
            raw.extend(
                penmesh_proxy::decode_stored_samples(layout, &data).expect("a stored chunk"),
            );
        }
        let mesh = sqlx::query("SELECT glb, vertices, triangles FROM meshes WHERE stroke_id = ?")
            .bind(&id)
            .fetch_optional(&pool)
            .await
            .unwrap();
        let glb: Option<Vec<u8>> = mesh.as_ref().map(|m| m.get("glb"));
        strokes.push(StoredStroke {
            session: row.get("session_id"),
            status: row.get("status"),
            // As the proxy counts them: where the last chunk ends.
            n_points: spans.last().map_or(0, |&(seq, n)| seq + n),
            n_retained: row.get::<i64, _>("n_retained") as u64,
            raw,
            chunks: spans,
            mesh: mesh.map(|m| {
                (
                    m.get::<Vec<u8>, _>("glb").len() as u64,
                    m.get::<i64, _>("vertices") as u64,
                    m.get::<i64, _>("triangles") as u64,
                )
            }),
            glb,
            id,
        });
    }
    pool.close().await;
    strokes
}

/// Checks a stroke is stored once, complete, contiguous, done, and with its mesh.
pub fn assert_stored_complete(stored: &StoredStroke) {
    assert_eq!(stored.status, "done", "stroke {}", stored.id);
    assert_eq!(stored.raw.len() as u64, stored.n_points, "stroke {}", stored.id);
    let mut next = 0;
    for &(seq, n) in &stored.chunks {
        assert_eq!(seq, next, "stroke {}: chunks overlap or leave a gap", stored.id);
        next += n;
    }
    assert!(stored.mesh.is_some(), "stroke {} has no mesh", stored.id);
}
