//! The client's side of a WebSocket to the proxy: opening it with the session's token, frames
//! to and from typed messages, and the `Hello` → `Welcome` handshake. Used by the live path
//! ([`crate::live`]) and by `penmesh-lab load`, so both speak the protocol the same way.

use std::time::Duration;

use futures_util::{Stream, StreamExt};
use penmesh::protocol::{
    ClientMessage, ErrorMessage, Hello, PROTOCOL_VERSION, ServerMessage, StrokeId, Welcome,
    decode_server, decode_server_json, encode_client,
};
use tokio::net::TcpStream;
use tokio_tungstenite::tungstenite::client::IntoClientRequest;
use tokio_tungstenite::tungstenite::protocol::WebSocketConfig;
use tokio_tungstenite::tungstenite::{self, Message};
use tokio_tungstenite::{MaybeTlsStream, WebSocketStream};

/// An open WebSocket to the proxy.
pub type Socket = WebSocketStream<MaybeTlsStream<TcpStream>>;

/// Why a WebSocket could not be opened.
#[derive(Debug, thiserror::Error)]
pub enum OpenError {
    /// The URL or the token cannot make a request; trying again will not help.
    #[error("{0}")]
    BadRequest(String),
    #[error("no answer within {} s", .0.as_secs())]
    Timeout(Duration),
    /// The proxy answered the upgrade with an HTTP status (401: wrong session or token).
    #[error("HTTP {status}{}", if .status.as_u16() == 401 { " (wrong session or token)" } else { "" })]
    Refused { status: tungstenite::http::StatusCode },
    #[error("{0}")]
    Failed(tungstenite::Error),
}

/// Opens `url` with `Authorization: Bearer token`, with Nagle's algorithm off (small frames go
/// out at once: otherwise a `StrokeEnd` right after a batch waits for the proxy's delayed ACK,
/// about 40 ms).
pub async fn open(
    url: &str,
    token: &str,
    config: Option<WebSocketConfig>,
    timeout: Duration,
) -> Result<Socket, OpenError> {
    let mut request = url
        .into_client_request()
        .map_err(|e| OpenError::BadRequest(format!("bad server URL {url}: {e}")))?;
    let bearer = format!("Bearer {token}").parse().map_err(|_| {
        OpenError::BadRequest("the token has characters a header cannot carry".into())
    })?;
    request.headers_mut().insert("authorization", bearer);
    match tokio::time::timeout(
        timeout,
        tokio_tungstenite::connect_async_with_config(request, config, true),
    )
    .await
    {
        Err(_) => Err(OpenError::Timeout(timeout)),
        Ok(Err(tungstenite::Error::Http(response))) => {
            Err(OpenError::Refused { status: response.status() })
        }
        Ok(Err(err)) => Err(OpenError::Failed(err)),
        Ok(Ok((ws, _))) => Ok(ws),
    }
}

/// A message as a binary frame (the compact encoding).
pub fn frame(msg: &ClientMessage) -> Message {
    Message::Binary(encode_client(msg).into())
}

/// The message a frame carries: `None` for control frames (tungstenite answers pings); an
/// error for a close or an undecodable frame.
pub fn decode_frame(frame: Message) -> Option<anyhow::Result<ServerMessage>> {
    match frame {
        Message::Binary(bytes) => Some(
            decode_server(&bytes, usize::MAX)
                .map_err(|e| anyhow::anyhow!("undecodable message from the proxy: {e}")),
        ),
        Message::Text(text) => Some(
            decode_server_json(&text, usize::MAX)
                .map_err(|e| anyhow::anyhow!("undecodable message from the proxy: {e}")),
        ),
        Message::Close(close) => Some(Err(anyhow::anyhow!(
            "the proxy closed the connection{}",
            close.map(|c| format!(" ({} {})", c.code, c.reason)).unwrap_or_default()
        ))),
        _ => None,
    }
}

/// A new participant key (`Hello.key`): 32 hex digits of 128 random bits from the operating
/// system's generator. Made once per person drawing and kept for the process, so every
/// reconnect is the same participant.
pub fn new_participant_key() -> String {
    format!("{:032x}", rand::random::<u128>())
}

/// The first message of a connection, as the participant of `key`.
pub fn hello(
    client: &str,
    name: Option<String>,
    resume: Vec<StrokeId>,
    key: Option<String>,
) -> ClientMessage {
    ClientMessage::Hello(Hello {
        protocol: PROTOCOL_VERSION,
        client: format!("{client}/{}", env!("CARGO_PKG_VERSION")),
        name,
        resume,
        key,
    })
}

/// The messages of a socket, as [`decode_frame`] reads its frames.
pub fn messages(socket: &mut Socket) -> impl Stream<Item = anyhow::Result<ServerMessage>> + '_ {
    socket.filter_map(|frame| {
        std::future::ready(match frame {
            Ok(frame) => decode_frame(frame),
            Err(err) => Some(Err(anyhow::anyhow!("connection lost: {err}"))),
        })
    })
}

/// Waits for the proxy's answer to `Hello`, passing over anything else: `Ok(Welcome)`, or
/// `Err(ErrorMessage)` when the proxy refused. `messages` ends when the connection does.
pub async fn await_welcome(
    timeout: Duration,
    mut messages: impl Stream<Item = anyhow::Result<ServerMessage>> + Unpin,
) -> anyhow::Result<Result<Welcome, ErrorMessage>> {
    let answer = async {
        loop {
            match messages.next().await {
                Some(Ok(ServerMessage::Welcome(welcome))) => return Ok(Ok(welcome)),
                Some(Ok(ServerMessage::Error(refusal))) => return Ok(Err(refusal)),
                Some(Ok(_)) => continue,
                Some(Err(err)) => return Err(err),
                None => anyhow::bail!("the connection closed before the proxy's welcome"),
            }
        }
    };
    tokio::time::timeout(timeout, answer)
        .await
        .map_err(|_| anyhow::anyhow!("no welcome from the proxy within {} s", timeout.as_secs()))?
}
