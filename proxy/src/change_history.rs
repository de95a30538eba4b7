//! A stroke's history of changes (its placements, `GET /v1/strokes/{id}/placements`; its
//! solids, `GET /v1/strokes/{id}/solids`), read a page at a time: the one mechanism both
//! routes share. A page holds at most [`MAX_HISTORY_PAGE`] changes and says where the next
//! begins; [`MAX_HISTORY_READS`] pages are read at once on a replica, the next waits its turn.

use std::time::Duration;

use sqlx::Row;
use uuid::Uuid;

use crate::http::AppError;
use crate::state::AppState;
use crate::store::StrokeRow;

/// Most changes in one page of a stroke's history.
pub const MAX_HISTORY_PAGE: u64 = 1000;
/// Pages of histories read at once on one replica: each is a millisecond or so of a request
/// thread's CPU, and readers that loop must leave the others' work its cores; the next waits
/// its turn (up to [`HISTORY_WAIT`]), then 503 `busy`.
pub const MAX_HISTORY_READS: usize = 1;
/// How long a page waits for its turn before 503 `busy`, at most (half the request timeout at
/// most).
const HISTORY_WAIT: Duration = Duration::from_secs(10);

/// A page of a stroke's history.
#[derive(Debug, serde::Deserialize, utoipa::IntoParams)]
pub struct HistoryPage {
    /// The position in the history (0 is the stroke's begin) of the page's first change
    /// (default 0): the `next` of the page before.
    from: Option<u64>,
    /// Most changes in the page (default and most: 1000).
    limit: Option<u64>,
}

/// A history's table: each row a change of one stroke, with who, when and why.
pub(crate) struct Changes {
    /// `stroke_placements` or `stroke_solids`.
    table: &'static str,
    /// The column of the change's stored form.
    column: &'static str,
}

pub(crate) const PLACEMENTS: Changes = Changes { table: "stroke_placements", column: "matrix" };
pub(crate) const SOLIDS: Changes = Changes { table: "stroke_solids", column: "solid" };

/// One stored change: its stored form, who, when (ms) and why.
pub(crate) struct Change {
    pub stored: Vec<u8>,
    pub by: Uuid,
    pub at: i64,
    pub cause: String,
}

/// A page of a stroke's history, oldest first.
pub(crate) struct Page {
    /// The page begins with the stroke's begin, which has no row (a stroke begun without a
    /// placement or a solid has the default one, set by its drawer when it began).
    pub begin: bool,
    /// The stored changes after it.
    pub changes: Vec<Change>,
    /// The `from` of the next page, when the history goes on.
    pub next: Option<u64>,
}

/// The page `page` of `row`'s history in `changes`: a bounded read, one at a time per replica.
pub(crate) async fn read_page(
    state: &AppState,
    row: &StrokeRow,
    changes: &Changes,
    page: &HistoryPage,
) -> Result<Page, AppError> {
    let limit = match page.limit {
        Some(0) => return Err(AppError::BadRequest("limit=0: a page holds at least one".into())),
        limit => limit.unwrap_or(MAX_HISTORY_PAGE).min(MAX_HISTORY_PAGE),
    };
    let from = page.from.unwrap_or(0);
    let wait = HISTORY_WAIT.min(Duration::from_secs(state.config.request_timeout_secs) / 2);
    let _permit = state.history_read_permit(wait).await.ok_or_else(|| {
        AppError::Busy(format!(
            "{MAX_HISTORY_READS} pages of stroke histories are being read, the limit, and more \
             wait their turn; try again shortly"
        ))
    })?;
    let pool = state.store.pool();
    let Changes { table, column } = changes;
    // A stroke begun without one has no row for its begin: the default, implied.
    let first: Option<String> = sqlx::query_scalar(&format!(
        "SELECT cause FROM {table} WHERE stroke_id = $1 ORDER BY id LIMIT 1"
    ))
    .bind(row.id.to_string())
    .fetch_optional(pool)
    .await
    .map_err(anyhow::Error::from)?;
    let implied = first.as_deref().is_none_or(|cause| cause == "set");
    let begin = implied && from == 0;
    let wanted = limit - begin as u64;
    // One more than the page, to tell whether the history goes on: a bounded read.
    let rows = sqlx::query(&format!(
        "SELECT {column} AS stored, set_by, set_at, cause FROM {table} WHERE stroke_id = $1 \
         ORDER BY id LIMIT $2 OFFSET $3"
    ))
    .bind(row.id.to_string())
    .bind(i64::try_from(wanted + 1).unwrap_or(i64::MAX))
    .bind(i64::try_from(from.saturating_sub(implied as u64)).unwrap_or(i64::MAX))
    .fetch_all(pool)
    .await
    .map_err(anyhow::Error::from)?;
    let more = rows.len() as u64 > wanted;
    let changes = rows
        .into_iter()
        .take(wanted as usize)
        .map(|r| {
            let by: String = r.try_get("set_by")?;
            Ok(Change {
                stored: r.try_get("stored")?,
                by: Uuid::parse_str(&by)?,
                at: r.try_get("set_at")?,
                cause: r.try_get("cause")?,
            })
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    Ok(Page { begin, changes, next: more.then_some(from + limit) })
}
