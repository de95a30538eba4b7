//! Session events as PostgreSQL notifications of the transaction that commits them.

use crate::events::SessionEvent;

/// The `LISTEN/NOTIFY` channel that carries session events between replicas (PostgreSQL).
pub const EVENTS_CHANNEL: &str = "penmesh_events";

/// Queues `events` as notifications of the current PostgreSQL transaction: they are delivered
/// to every listening replica when (and only if) it commits, in commit order.
pub(crate) async fn notify(
    conn: &mut sqlx::AnyConnection,
    events: &[SessionEvent],
) -> anyhow::Result<()> {
    let payloads = SessionEvent::notify_payloads(events);
    for chunk in payloads.chunks(500) {
        let values: Vec<String> = (1..=chunk.len()).map(|i| format!("(${i})")).collect();
        let sql = format!(
            "SELECT COUNT(pg_notify('{EVENTS_CHANNEL}', v)) AS n FROM (VALUES {}) AS t (v)",
            values.join(", ")
        );
        let mut query = sqlx::query(&sql);
        for payload in chunk {
            query = query.bind(payload.as_str());
        }
        query.fetch_one(&mut *conn).await?;
    }
    Ok(())
}
