//! Why a message was not carried out and what the client hears of it: one enum for the
//! connection, answered, counted and logged in one place (`Connection::fail`).

use std::fmt::Display;

use penmesh::protocol::{ErrorCode, StrokeId};

use crate::ingest::Refusal;

/// Why the stream of frames could not give the next one.
#[derive(Debug)]
pub enum ReadError {
    /// A message past the hard size limit: the WebSocket layer refused to read it.
    TooLarge(String),
    /// The socket failed (reset, a broken frame): the client is gone.
    Broken(String),
}

/// A stream that cannot fail (a test's channel).
impl From<std::convert::Infallible> for ReadError {
    fn from(never: std::convert::Infallible) -> ReadError {
        match never {}
    }
}

/// How a connection ends.
#[derive(Debug, Clone, PartialEq)]
pub(super) enum End {
    /// The client closed or vanished.
    Gone,
    /// Close with this code and reason.
    Close(u16, String),
    /// The outgoing queue is full: drop the connection.
    SlowReader,
}

/// A message that was not carried out.
#[derive(Debug)]
pub(super) enum ConnError {
    /// Bad input, or a request that cannot be granted: answered with `Error {code}`; the
    /// connection goes on.
    Refused { code: ErrorCode, message: String, stroke: Option<StrokeId> },
    /// A failure on the proxy's side (storage): logged with its cause, answered with
    /// `Error {internal}` and what the client can do; the connection goes on.
    Internal { doing: &'static str, cause: String, advice: String, stroke: Option<StrokeId> },
    /// Answered, then the connection ends.
    Fatal { code: ErrorCode, message: String, end: End },
}

impl ConnError {
    pub fn refused(code: ErrorCode, message: impl Into<String>, stroke: Option<StrokeId>) -> Self {
        ConnError::Refused { code, message: message.into(), stroke }
    }

    pub fn internal(
        doing: &'static str,
        cause: impl Display,
        advice: impl Into<String>,
        stroke: Option<StrokeId>,
    ) -> Self {
        ConnError::Internal { doing, cause: cause.to_string(), advice: advice.into(), stroke }
    }

    pub fn fatal(code: ErrorCode, message: impl Into<String>, end: End) -> Self {
        ConnError::Fatal { code, message: message.into(), end }
    }

    /// A refusal of the stroke state machine ([`crate::ingest`]), about `stroke`.
    pub fn from_refusal(refusal: Refusal, stroke: Option<StrokeId>) -> Self {
        ConnError::Refused { code: refusal.code, message: refusal.message, stroke }
    }

    /// The answer's code.
    pub fn code(&self) -> ErrorCode {
        match self {
            ConnError::Refused { code, .. } | ConnError::Fatal { code, .. } => *code,
            ConnError::Internal { .. } => ErrorCode::Internal,
        }
    }
}
