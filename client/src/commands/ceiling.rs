//! `penmesh ceiling` (hidden): the most a server on the proxy's stack can do, for `penmesh load`
//! to measure the proxy against.
//!
//! The same stack as the proxy (axum's WebSocket on tokio, the same binary codec), and nothing
//! else: it decodes each frame and answers at once — `Welcome` to `Hello`, `Ack` to
//! `StrokeBegin` and to every `Points` batch, `StrokeDone` to `StrokeEnd`, `Pong` to `Ping`.
//! No token check, no ACUTS, no database, no fan-out. `POST /v1/sessions` hands out a session
//! marked `"ceiling": true`, so the load tool knows there is nothing stored to count back.

use anyhow::Context;
use axum::Router;
use axum::extract::Path;
use axum::extract::ws::{Message, WebSocket, WebSocketUpgrade};
use axum::http::StatusCode;
use axum::response::Response;
use axum::routing::{get, post};
use axum::serve::ListenerExt;
use clap::Args;
use penmesh::protocol::{
    Ack, ClientMessage, MAX_FRAME_BYTES_DEFAULT, PROTOCOL_VERSION, ServerMessage, StrokeDone,
    Welcome, decode_client, encode_server,
};
use uuid::Uuid;

#[derive(Debug, Args)]
pub struct CeilingArgs {
    /// Address to listen on.
    #[arg(long, default_value = "127.0.0.1")]
    pub host: String,
    /// Port to listen on (0 picks a free one; the address is printed).
    #[arg(long, default_value_t = 0)]
    pub port: u16,
}

pub fn run(args: &CeilingArgs) -> anyhow::Result<()> {
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()
        .context("starting the runtime")?;
    runtime.block_on(async {
        let listener = tokio::net::TcpListener::bind((args.host.as_str(), args.port))
            .await
            .with_context(|| format!("binding {}:{}", args.host, args.port))?;
        println!("ceiling listening on http://{}", listener.local_addr()?);
        // TCP_NODELAY, as the proxy: no answer waits for the ACK of the one before.
        let listener = listener.tap_io(|tcp| drop(tcp.set_nodelay(true)));
        axum::serve(listener, router()).await.context("serving")
    })
}

/// The ceiling's routes: a session, the WebSocket and a health check.
pub fn router() -> Router {
    Router::new()
        .route("/v1/sessions", post(new_session))
        .route("/v1/sessions/{session}/ws", get(upgrade))
        .route("/healthz", get(|| async { "ok" }))
}

async fn new_session() -> (StatusCode, axum::Json<serde_json::Value>) {
    let body = serde_json::json!({"session": Uuid::new_v4(), "token": "ceiling", "ceiling": true});
    (StatusCode::CREATED, axum::Json(body))
}

async fn upgrade(Path(session): Path<Uuid>, ws: WebSocketUpgrade) -> Response {
    // The proxy's read buffer (see proxy/src/ws/adapter.rs), so both measure the same stack.
    ws.read_buffer_size(4 * 1024).on_upgrade(move |socket| serve(socket, session))
}

/// Decodes each binary frame and answers it; anything undecodable ends the connection.
async fn serve(mut socket: WebSocket, session: Uuid) {
    while let Some(Ok(frame)) = socket.recv().await {
        let bytes = match frame {
            Message::Binary(bytes) => bytes,
            Message::Close(_) => return,
            _ => continue,
        };
        let Ok(msg) = decode_client(&bytes, MAX_FRAME_BYTES_DEFAULT) else { return };
        let reply = match msg {
            ClientMessage::Hello(_) => ServerMessage::Welcome(Welcome {
                protocol: PROTOCOL_VERSION,
                session,
                participant: Uuid::new_v4(),
                resume: Vec::new(),
            }),
            ClientMessage::StrokeBegin(begin) => {
                ServerMessage::Ack(Ack { stroke: begin.stroke, upto_seq: 0 })
            }
            ClientMessage::Points(points) => ServerMessage::Ack(Ack {
                stroke: points.stroke,
                upto_seq: points.seq + points.points.0.len() as u64,
            }),
            ClientMessage::StrokeEnd(end) => ServerMessage::StrokeDone(StrokeDone {
                stroke: end.stroke,
                n_retained: 0,
                url: format!("/v1/strokes/{}/simplified", end.stroke),
            }),
            ClientMessage::Ping(ping) => ServerMessage::Pong(ping),
        };
        if socket.send(Message::Binary(encode_server(&reply).into())).await.is_err() {
            return;
        }
    }
}
