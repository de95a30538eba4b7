//! The deadline of sending an HTTP response: a response (its body included) must be written to
//! the socket within `--request-timeout-secs` of its request's start, or the connection is
//! closed. The request timeout alone ends when the response's head is ready; a client that
//! then reads a large body slowly, or not at all, would hold it (and the permit of a large
//! body, `AppState::large_body`) for as long as it liked.
//!
//! hyper writes a body only as fast as the socket takes it and polls the body no further
//! meanwhile, so the deadline is kept by the socket: [`DeadlineIo`] fails a write that is
//! still waiting for room after the deadline of the request being answered
//! ([`SendDeadline`]). The serve loop wraps every connection's socket in it and clears the
//! deadline at each request; [`arm`] sets it on the routes it layers (not the WebSocket, whose
//! upgraded socket is the same one, without a deadline).

use std::io;
use std::pin::Pin;
use std::sync::{Arc, Mutex};
use std::task::{Context, Poll, ready};
use std::time::Duration;

use axum::extract::{Request, State};
use axum::middleware::Next;
use axum::response::Response;
use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};
use tokio::time::{Instant, Sleep};

/// The send deadline of one connection's current response (`None`: no deadline).
#[derive(Debug, Clone, Default)]
pub struct SendDeadline(Arc<Mutex<Option<Instant>>>);

impl SendDeadline {
    pub fn set(&self, at: Option<Instant>) {
        *self.0.lock().expect("send deadline lock") = at;
    }

    fn get(&self) -> Option<Instant> {
        *self.0.lock().expect("send deadline lock")
    }
}

/// Sets the send deadline of the request's connection: `timeout` from now.
pub async fn arm(State(timeout): State<Duration>, request: Request, next: Next) -> Response {
    if let Some(deadline) = request.extensions().get::<SendDeadline>() {
        deadline.set(Some(Instant::now() + timeout));
    }
    next.run(request).await
}

/// A socket whose writes fail once they wait past the connection's [`SendDeadline`].
#[derive(Debug)]
pub struct DeadlineIo<T> {
    io: T,
    deadline: SendDeadline,
    /// The timer of the deadline last seen, and that deadline.
    timer: Option<(Instant, Pin<Box<Sleep>>)>,
}

impl<T> DeadlineIo<T> {
    pub fn new(io: T, deadline: SendDeadline) -> DeadlineIo<T> {
        DeadlineIo { io, deadline, timer: None }
    }

    /// A write that waits for room: an error once the deadline has passed, else pending
    /// (woken by the socket, or by the deadline's timer).
    fn waiting<R>(&mut self, cx: &mut Context<'_>) -> Poll<io::Result<R>> {
        let Some(at) = self.deadline.get() else { return Poll::Pending };
        if self.timer.as_ref().is_none_or(|(armed, _)| *armed != at) {
            self.timer = Some((at, Box::pin(tokio::time::sleep_until(at))));
        }
        let (_, timer) = self.timer.as_mut().expect("armed above");
        ready!(timer.as_mut().poll(cx));
        Poll::Ready(Err(io::Error::new(
            io::ErrorKind::TimedOut,
            "the client did not take the response within the request timeout",
        )))
    }
}

impl<T: AsyncRead + Unpin> AsyncRead for DeadlineIo<T> {
    fn poll_read(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &mut ReadBuf<'_>,
    ) -> Poll<io::Result<()>> {
        Pin::new(&mut self.io).poll_read(cx, buf)
    }
}

impl<T: AsyncWrite + Unpin> AsyncWrite for DeadlineIo<T> {
    fn poll_write(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &[u8],
    ) -> Poll<io::Result<usize>> {
        match Pin::new(&mut self.io).poll_write(cx, buf) {
            Poll::Pending => self.waiting(cx),
            done => done,
        }
    }

    fn poll_write_vectored(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        bufs: &[io::IoSlice<'_>],
    ) -> Poll<io::Result<usize>> {
        match Pin::new(&mut self.io).poll_write_vectored(cx, bufs) {
            Poll::Pending => self.waiting(cx),
            done => done,
        }
    }

    fn is_write_vectored(&self) -> bool {
        self.io.is_write_vectored()
    }

    fn poll_flush(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        match Pin::new(&mut self.io).poll_flush(cx) {
            Poll::Pending => self.waiting(cx),
            done => done,
        }
    }

    fn poll_shutdown(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.io).poll_shutdown(cx)
    }
}

#[cfg(test)]
mod tests {
    use tokio::io::AsyncWriteExt;

    use super::*;

    // A write that waits for a reader who never reads fails at the deadline, and not before
    // one is set.
    #[tokio::test(start_paused = true)]
    async fn a_write_that_waits_past_the_deadline_fails() {
        let (client, _server) = tokio::io::duplex(16);
        let deadline = SendDeadline::default();
        let mut io = DeadlineIo::new(client, deadline.clone());
        io.write_all(&[0; 16]).await.unwrap();
        let waits = tokio::time::timeout(Duration::from_secs(60), io.write_all(&[0; 16]));
        assert!(waits.await.is_err(), "no deadline: the write waits");
        deadline.set(Some(Instant::now() + Duration::from_secs(5)));
        let err = io.write_all(&[0; 16]).await.unwrap_err();
        assert_eq!(err.kind(), io::ErrorKind::TimedOut);
    }
}
