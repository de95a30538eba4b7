//! A TCP forwarder between the proxy and PostgreSQL that can fail the network under them.
//!
//! - [`Forwarder::reset_all`]: every connection open now is reset on both sides (RST), as when
//!   a load balancer or the server restarts; connections made later flow.
//!   [`Forwarder::reset_where`] resets those whose `application_name` (read from the startup
//!   message) passes a test: the listener's, the stroke locks', or the others.
//! - [`Forwarder::black_hole`]: nothing flows any more, on the connections open now and on new
//!   ones (accepted, then silent), and no side learns of it: a network partition.
//! - [`Forwarder::heal`]: new connections flow again. The connections that lived through the
//!   partition stay lost, as after a partition longer than TCP's own timeouts: the server has
//!   given up on them (its side is closed, which ends its transactions and frees its locks);
//!   the proxy's side hears nothing ever again, and is reset only when it sends something (the
//!   server answers a segment of a connection it forgot with RST). A connection waiting to be
//!   told something (the `LISTEN` connection, a query awaiting its answer) waits forever.

use std::net::SocketAddr;
use std::sync::Arc;

use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::watch;

/// Which connections a targeted reset hits, by `application_name` ("" when it has none).
type Pick = Arc<dyn Fn(&str) -> bool + Send + Sync>;

/// What the network does now.
#[derive(Clone, Default)]
struct Weather {
    /// Bumped by every [`Forwarder::reset_all`].
    resets: u64,
    /// Bumped by every [`Forwarder::reset_where`], which sets `pick`.
    targeted: u64,
    pick: Option<Pick>,
    /// Bumped by every [`Forwarder::heal`] after a black hole.
    heals: u64,
    black_hole: bool,
}

/// A running forwarder; stops when dropped.
pub struct Forwarder {
    pub addr: SocketAddr,
    weather: Arc<watch::Sender<Weather>>,
    task: tokio::task::JoinHandle<()>,
}

impl Drop for Forwarder {
    fn drop(&mut self) {
        self.task.abort();
        // Every connection task watches the weather: closing it ends them.
        self.weather.send_modify(|w| w.resets += 1);
    }
}

impl Forwarder {
    /// Listens on a free loopback port and forwards every connection to `target`.
    pub async fn start(target: SocketAddr) -> Forwarder {
        let listener = TcpListener::bind("127.0.0.1:0").await.expect("the forwarder binds");
        let addr = listener.local_addr().unwrap();
        let weather = Arc::new(watch::Sender::new(Weather::default()));
        let shared = weather.clone();
        let task = tokio::spawn(async move {
            loop {
                let Ok((client, _)) = listener.accept().await else { continue };
                let rx = shared.subscribe();
                tokio::spawn(async move {
                    if let Ok(server) = TcpStream::connect(target).await {
                        carry(client, server, rx).await;
                    }
                });
            }
        });
        Forwarder { addr, weather, task }
    }

    /// Resets every connection open now (both sides get an RST).
    pub fn reset_all(&self) {
        self.weather.send_modify(|w| w.resets += 1);
    }

    /// Resets the connections open now whose `application_name` passes `pick`.
    pub fn reset_where(&self, pick: impl Fn(&str) -> bool + Send + Sync + 'static) {
        self.weather.send_modify(|w| {
            w.targeted += 1;
            w.pick = Some(Arc::new(pick));
        });
    }

    /// Stops all traffic, telling no one.
    pub fn black_hole(&self) {
        self.weather.send_modify(|w| w.black_hole = true);
    }

    /// New connections flow again; those that lived through the black hole stay lost.
    pub fn heal(&self) {
        self.weather.send_modify(|w| {
            if w.black_hole {
                w.black_hole = false;
                w.heals += 1;
            }
        });
    }

    /// The URL `url` (a PostgreSQL URL) would have if its server were this forwarder.
    pub fn rewrite_url(&self, url: &str) -> String {
        let scheme_end = url.find("://").expect("a URL") + 3;
        let rest = &url[scheme_end..];
        let host_end = rest.find(['/', '?']).unwrap_or(rest.len());
        let authority = &rest[..host_end];
        let user = authority.rfind('@').map(|at| &authority[..=at]).unwrap_or("");
        let url = format!("{}{user}{}{}", &url[..scheme_end], self.addr, &rest[host_end..]);
        // In plain text, so that the forwarder can read each connection's application_name
        // (the proxy speaks TLS to a server that offers it, as this machine's does).
        let joiner = if url.contains('?') { '&' } else { '?' };
        format!("{url}{joiner}sslmode=disable")
    }
}

fn reset(stream: TcpStream) {
    let _ = stream.set_zero_linger();
    drop(stream);
}

/// Carries one connection's bytes both ways while the weather lets it.
async fn carry(mut client: TcpStream, mut server: TcpStream, mut rx: watch::Receiver<Weather>) {
    let born = rx.borrow_and_update().clone();
    let mut partitioned = born.black_hole;
    let mut targeted = born.targeted;
    // The start of what the proxy sent, until its application_name is found in it.
    let (mut sniffed, mut application) = (Vec::new(), None::<String>);
    let (mut up, mut down) = (vec![0u8; 16 * 1024], vec![0u8; 16 * 1024]);
    loop {
        let now = rx.borrow_and_update().clone();
        let picked = now.targeted != targeted
            && now.pick.as_ref().is_some_and(|pick| pick(application.as_deref().unwrap_or("")));
        targeted = now.targeted;
        if now.resets != born.resets || picked {
            reset(client);
            reset(server);
            return;
        }
        // A heal since it was born means it lived through a black hole.
        partitioned |= now.black_hole || now.heals != born.heals;
        if partitioned && !now.black_hole {
            return lost(client, server, rx, born).await;
        }
        if partitioned {
            if rx.changed().await.is_err() {
                return;
            }
            continue;
        }
        tokio::select! {
            changed = rx.changed() => if changed.is_err() { return },
            read = client.read(&mut up) => match read {
                Ok(0) | Err(_) => { let _ = server.shutdown().await; return drain(server, &mut down).await }
                Ok(n) => {
                    if application.is_none() && sniffed.len() < 4096 {
                        sniffed.extend_from_slice(&up[..n]);
                        application = application_name(&sniffed);
                    }
                    if server.write_all(&up[..n]).await.is_err() { return reset(client) }
                }
            },
            read = server.read(&mut down) => match read {
                Ok(0) | Err(_) => { let _ = client.shutdown().await; return drain(client, &mut up).await }
                Ok(n) => if client.write_all(&down[..n]).await.is_err() { return reset(server) },
            },
        }
    }
}

/// The `application_name` of a PostgreSQL startup message in `bytes`, once it is all there.
fn application_name(bytes: &[u8]) -> Option<String> {
    let key = b"application_name\0";
    let at = bytes.windows(key.len()).position(|w| w == key)? + key.len();
    let len = bytes[at..].iter().position(|&b| b == 0)?;
    Some(String::from_utf8_lossy(&bytes[at..at + len]).into_owned())
}

/// Reads what is left of a side that the other has closed, until it closes too.
async fn drain(mut stream: TcpStream, buf: &mut [u8]) {
    while let Ok(n) = stream.read(buf).await {
        if n == 0 {
            return;
        }
    }
}

/// A connection that lived through a partition: the server's side closes, the proxy's side is
/// silent until it sends something, which resets it. A later `reset_all` resets it too.
async fn lost(
    client: TcpStream,
    server: TcpStream,
    mut rx: watch::Receiver<Weather>,
    born: Weather,
) {
    drop(server);
    let mut client = client;
    let mut buf = [0u8; 1024];
    loop {
        tokio::select! {
            changed = rx.changed() => {
                if changed.is_err() || rx.borrow_and_update().resets != born.resets {
                    return reset(client);
                }
            }
            _ = client.read(&mut buf) => return reset(client),
        }
    }
}
