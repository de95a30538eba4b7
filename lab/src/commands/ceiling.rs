//! `penmesh-lab ceiling` (hidden): the most a server on the proxy's stack can do, for `penmesh-lab load`
//! to measure the proxy against.
//!
//! The same stack as the proxy (axum's WebSocket on tokio, the same binary codec), and nothing
//! else: it decodes each frame and answers at once — `Welcome` to `Hello`, `Ack` to
//! `StrokeBegin` and to every `Points` batch, `StrokeDone` to `StrokeEnd`, `Pong` to `Ping`.
//! No token check, no ACUTS, no database, no fan-out. `POST /v1/sessions` hands out a session
//! marked `"ceiling": true`, so the load tool knows there is nothing stored to count back.
//!
//! `--answer-task` answers through the proxy's own pieces (`proxy/src/ws/adapter.rs`,
//! `outgoing.rs`): the socket split in two, the answers in a bounded queue, and a task of its own
//! writing them to the socket.
//! Against the plain ceiling, that measures what this structure costs by itself.

use anyhow::Context;
use axum::Router;
use axum::extract::Path;
use axum::extract::ws::{Message, WebSocket, WebSocketUpgrade};
use axum::http::StatusCode;
use axum::response::Response;
use axum::routing::{get, post};
use axum::serve::ListenerExt;
use clap::Args;
use futures_util::StreamExt;
use penmesh::protocol::{
    Ack, ClientMessage, ErrorCode, ErrorMessage, MAX_FRAME_BYTES_DEFAULT, PROTOCOL_VERSION,
    ServerMessage, SetPlacement, StrokeDone, StrokeRef, Welcome, decode_client, encode_server,
};
use penmesh_proxy::Frame;
use uuid::Uuid;

#[derive(Debug, Args)]
pub struct CeilingArgs {
    /// Address to listen on.
    #[arg(long, default_value = "127.0.0.1")]
    pub host: String,
    /// Port to listen on (0 picks a free one; the address is printed).
    #[arg(long, default_value_t = 0)]
    pub port: u16,
    /// Answer through a bounded queue and a writing task of its own, as the proxy does.
    #[arg(long)]
    pub answer_task: bool,
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
        axum::serve(listener, router(args.answer_task)).await.context("serving")
    })
}

/// The ceiling's routes: a session, the WebSocket and a health check. `answer_task`: see the
/// module's comment.
pub fn router(answer_task: bool) -> Router {
    let upgrade = move |path: Path<Uuid>, ws: WebSocketUpgrade| upgrade(path, ws, answer_task);
    Router::new()
        .route("/v1/sessions", post(new_session))
        .route("/v1/sessions/{session}/ws", get(upgrade))
        .route("/healthz", get(|| async { "ok" }))
}

async fn new_session() -> (StatusCode, axum::Json<serde_json::Value>) {
    let body = serde_json::json!({"session": Uuid::new_v4(), "token": "ceiling", "ceiling": true});
    (StatusCode::CREATED, axum::Json(body))
}

async fn upgrade(Path(session): Path<Uuid>, ws: WebSocketUpgrade, answer_task: bool) -> Response {
    // The proxy's read buffer (see proxy/src/ws/adapter.rs), so both measure the same stack.
    let ws = ws.read_buffer_size(4 * 1024);
    if answer_task {
        ws.on_upgrade(move |socket| serve_through_task(socket, session))
    } else {
        ws.on_upgrade(move |socket| serve(socket, session))
    }
}

/// Decodes each binary frame and answers it; anything undecodable ends the connection.
async fn serve(mut socket: WebSocket, session: Uuid) {
    while let Some(Ok(frame)) = socket.recv().await {
        let bytes = match frame {
            Message::Binary(bytes) => bytes,
            Message::Close(_) => return,
            _ => continue,
        };
        let Some(reply) = answer(&bytes, session) else { return };
        if socket.send(Message::Binary(reply.into())).await.is_err() {
            return;
        }
    }
}

/// [`serve`] through the proxy's own pieces: its socket adapter, a queue of the proxy's
/// default length (`--outgoing-queue`), and its task that writes the queued frames.
async fn serve_through_task(socket: WebSocket, session: Uuid) {
    let (sink, mut stream) = penmesh_proxy::split_socket(socket);
    let (queue, frames) = tokio::sync::mpsc::channel(1024);
    let writer = tokio::spawn(penmesh_proxy::forward_frames(frames, sink));
    while let Some(Ok(frame)) = stream.next().await {
        let bytes = match frame {
            Frame::Binary(bytes) => bytes,
            Frame::Close(_) => break,
            _ => continue,
        };
        let Some(reply) = answer(&bytes, session) else { break };
        if queue.try_send(Frame::Binary(reply)).is_err() {
            break;
        }
    }
    drop(queue);
    let _ = writer.await;
}

/// The encoded answer to a binary frame; `None` when it does not decode.
fn answer(bytes: &[u8], session: Uuid) -> Option<Vec<u8>> {
    let reply = match decode_client(bytes, MAX_FRAME_BYTES_DEFAULT).ok()? {
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
            url: penmesh_client::api::stroke_simplified(end.stroke),
        }),
        ClientMessage::Ping(ping) => ServerMessage::Pong(ping),
        // The load tool never takes a stroke back nor renames; a no-op answer all the same.
        ClientMessage::SetPlacement(SetPlacement { stroke, .. })
        | ClientMessage::SetSolid(penmesh::protocol::SetSolid { stroke, .. })
        | ClientMessage::RemoveStroke(StrokeRef { stroke })
        | ClientMessage::RestoreStroke(StrokeRef { stroke }) => {
            ServerMessage::Error(ErrorMessage {
                code: ErrorCode::UnknownStroke,
                message: format!("the ceiling keeps no strokes ({stroke})"),
                stroke: Some(stroke),
            })
        }
        ClientMessage::Rename(_) => ServerMessage::Error(ErrorMessage {
            code: ErrorCode::UnknownMessage,
            message: "the ceiling keeps no names".into(),
            stroke: None,
        }),
    };
    Some(encode_server(&reply))
}
