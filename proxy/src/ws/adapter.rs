//! `GET /v1/sessions/{session}/ws`: authenticate, upgrade, and axum's WebSocket as a
//! `Sink`/`Stream` of [`Frame`]s for [`serve`].

use std::net::{Ipv4Addr, SocketAddr};

use axum::Extension;
use axum::extract::ws::{CloseFrame, Message, WebSocket, WebSocketUpgrade};
use axum::extract::{ConnectInfo, Path, State};
use axum::http::HeaderMap;
use axum::response::{IntoResponse, Response};
use futures_util::{Sink, SinkExt, Stream, StreamExt};
use penmesh::protocol::{ErrorCode, ErrorMessage, ServerMessage, encode_server_json};

use super::error::ReadError;
use super::{Frame, close_code, serve};
use crate::http::{AppError, authorize_session};
use crate::stages::{self, Stage};
use crate::state::{AppState, NoSlot};

/// `GET /v1/sessions/{session}/ws`: authenticates, then upgrades.
pub async fn ws_handler(
    State(state): State<AppState>,
    Path(session): Path<String>,
    headers: HeaderMap,
    peer: Option<Extension<ConnectInfo<SocketAddr>>>,
    upgrade: Result<WebSocketUpgrade, axum::extract::ws::rejection::WebSocketUpgradeRejection>,
) -> Result<Response, AppError> {
    if state.shutdown.is_cancelled() {
        return Err(AppError::ShuttingDown);
    }
    // A browser cannot set headers on a WebSocket: it offers its token as a subprotocol. A
    // token in the query string is not read (URLs reach access logs).
    let token = crate::web::subprotocol_token(&headers);
    let authorized = authorize_session(&state, &headers, token, &session).await;
    let upgrade = match upgrade {
        Ok(upgrade) => upgrade,
        Err(rejection) => {
            authorized?;
            return Ok(rejection.into_response());
        }
    };
    let session = match authorized {
        Ok(session) => session,
        // A browser's WebSocket sees a refused upgrade only as code 1006, the same as a network
        // that failed: a browser (its token offered as a subprotocol) is told in a close code of
        // its own, which it does not retry. Other clients get the HTTP 401.
        Err(AppError::Unauthorized) if token.is_some() => {
            let upgrade = upgrade.protocols([crate::web::SUBPROTOCOL]);
            return Ok(upgrade.on_upgrade(|socket| async move {
                let (mut sink, _) = split(socket);
                let reason = "unauthorized: no session of this id opens with this token";
                let _ =
                    sink.send(Frame::Close(Some((close_code::UNAUTHORIZED, reason.into())))).await;
            }));
        }
        Err(err) => return Err(err),
    };
    // The serve loop always gives the peer; a request handed to the router directly (a test)
    // counts as the unspecified address.
    let peer = peer.map_or((Ipv4Addr::UNSPECIFIED, 0).into(), |Extension(ConnectInfo(p))| p);
    let address = crate::rate::client_key(peer, &headers, state.config.trust_forwarded_for);
    let slot = state.connection_slot(address).map_err(|why| {
        AppError::Busy(match why {
            NoSlot::Replica => format!(
                "this replica has {} WebSocket connections, the limit (--max-connections)",
                state.config.max_connections
            ),
            NoSlot::Address => format!(
                "this replica has {} WebSocket connections from {address}, the limit per client \
                 address (--max-connections-per-address)",
                state.config.max_connections_per_address
            ),
        })
    })?;
    let hard = state.config.hard_message_limit();
    let guard = state.join_session(session);
    let tracked = state.tracker.token();
    let upgrade = upgrade.read_buffer_size(READ_BUFFER_BYTES).protocols([crate::web::SUBPROTOCOL]);
    Ok(upgrade.max_message_size(hard).max_frame_size(hard).on_upgrade(move |socket| async move {
        let (_tracked, _slot) = (tracked, slot);
        let (sink, stream) = split(socket);
        let stream = stages::timed(Stage::Read, stream);
        match guard {
            Some(guard) => {
                stages::timed(Stage::ConnectionTask, serve(state, session, guard, sink, stream))
                    .await
            }
            None => refuse_full_session(state, sink).await,
        }
    }))
}

/// Socket read buffer per connection. tungstenite zero-fills the whole buffer on its first
/// read, so its default (128 KiB) would make every idle connection cost that much resident
/// memory; `Points` frames are a few hundred bytes, and larger messages still arrive whole
/// (the buffer grows for them).
const READ_BUFFER_BYTES: usize = 4 * 1024;

pub type FrameSink = std::pin::Pin<Box<dyn Sink<Frame, Error = axum::Error> + Send>>;
pub type FrameStream = std::pin::Pin<Box<dyn Stream<Item = Result<Frame, ReadError>> + Send>>;

/// axum's WebSocket as the `Sink`/`Stream` of [`Frame`]s the connection loop works with (public
/// for the ceiling, which measures this structure alone).
pub fn split(socket: WebSocket) -> (FrameSink, FrameStream) {
    let (sink, stream) = socket.split();
    let sink = sink.with(|frame: Frame| {
        futures_util::future::ready(Ok::<_, axum::Error>(match frame {
            Frame::Text(text) => Message::Text(text.into()),
            Frame::Binary(bytes) => Message::Binary(bytes.into()),
            Frame::Ping(bytes) => Message::Ping(bytes.into()),
            Frame::Pong(bytes) => Message::Pong(bytes.into()),
            Frame::Close(close) => Message::Close(
                close.map(|(code, reason)| CloseFrame { code, reason: reason.into() }),
            ),
        }))
    });
    let stream = stream.map(|msg| match msg {
        Ok(Message::Text(text)) => Ok(Frame::Text(text.to_string())),
        Ok(Message::Binary(bytes)) => Ok(Frame::Binary(bytes.to_vec())),
        Ok(Message::Ping(bytes)) => Ok(Frame::Ping(bytes.to_vec())),
        Ok(Message::Pong(bytes)) => Ok(Frame::Pong(bytes.to_vec())),
        Ok(Message::Close(close)) => {
            Ok(Frame::Close(close.map(|c| (c.code, c.reason.to_string()))))
        }
        Err(err) => Err(read_error(err)),
    });
    (Box::pin(sink), Box::pin(stream))
}

/// Tells a message past the size limit from a broken socket by the WebSocket library's own
/// error type (`tungstenite` is a dependency at the version axum's `ws` feature uses, for
/// this; the oversize test in `tests/tests/proxy/limits.rs` fails if the two drift apart).
fn read_error(err: axum::Error) -> ReadError {
    let err = err.into_inner();
    match err.downcast_ref::<tungstenite::Error>() {
        Some(tungstenite::Error::Capacity(capacity)) => ReadError::TooLarge(capacity.to_string()),
        _ => ReadError::Broken(err.to_string()),
    }
}

async fn refuse_full_session(state: AppState, mut sink: FrameSink) {
    metrics::counter!("penmesh_errors_total", "code" => ErrorCode::TooManyConnections.as_str())
        .increment(1);
    let msg = ServerMessage::Error(ErrorMessage {
        code: ErrorCode::TooManyConnections,
        message: format!(
            "this session already has {} connections, the limit",
            state.config.max_connections_per_session
        ),
        stroke: None,
    });
    // The client has said nothing yet: JSON is readable by everyone.
    let _ = sink.send(Frame::Text(encode_server_json(&msg))).await;
    let _ =
        sink.send(Frame::Close(Some((close_code::POLICY, "too many connections".into())))).await;
}
