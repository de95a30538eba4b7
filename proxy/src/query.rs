//! The query string of a request, read as axum's `Query` reads it, except that a query that
//! does not read (a parameter missing, or not of its type: `size_mm=abc`) is answered as every
//! other error is: 400 with the JSON error body (`AppError::BadRequest`), not axum's plain
//! text. Every route that reads a query takes it through this extractor.

use axum::extract::FromRequestParts;
use axum::http::request::Parts;
use serde::de::DeserializeOwned;

use crate::http::AppError;

/// A request's query string as `T`.
#[derive(Debug, Clone, Copy, Default)]
pub struct Query<T>(pub T);

impl<T: DeserializeOwned, S: Send + Sync> FromRequestParts<S> for Query<T> {
    type Rejection = AppError;

    async fn from_request_parts(parts: &mut Parts, state: &S) -> Result<Self, AppError> {
        match axum::extract::Query::<T>::from_request_parts(parts, state).await {
            Ok(axum::extract::Query(query)) => Ok(Query(query)),
            Err(rejection) => Err(AppError::BadRequest(format!(
                "the query string does not read: {}",
                rejection.body_text()
            ))),
        }
    }
}
