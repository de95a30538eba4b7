//! The server a run starts for itself (`--spawn-proxy`, `--spawn-ceiling`): this program as a
//! child process on a free loopback port, stopped with SIGTERM when the run ends.

use std::time::Duration;

use anyhow::Context;
use rustix::process::{Pid, Signal, kill_process};

use super::{LoadArgs, Plan};

/// A server this run started, stopped when dropped.
#[derive(Debug)]
pub(super) struct Spawned {
    pub(super) child: std::process::Child,
    dir: tempfile::TempDir,
}

impl Drop for Spawned {
    fn drop(&mut self) {
        // SIGTERM lets the proxy shut down gracefully; kill it if it does not within 15 s.
        let _ = kill_process(Pid::from_child(&self.child), Signal::TERM);
        let deadline = std::time::Instant::now() + Duration::from_secs(15);
        while std::time::Instant::now() < deadline {
            if let Ok(Some(_)) = self.child.try_wait() {
                return;
            }
            std::thread::sleep(Duration::from_millis(50));
        }
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Starts the proxy (`penmesh-lab serve-proxy`, the same code as `penmesh-proxy`) or the ceiling on
/// a free loopback port and waits until it answers.
pub(super) fn spawn_server(args: &LoadArgs, plan: &Plan) -> anyhow::Result<(String, Spawned)> {
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .context("cannot find a free port")?
        .port();
    let dir = tempfile::Builder::new().prefix("penmesh-load-").tempdir()?;
    let exe = std::env::current_exe().context("cannot find this program")?;
    let mut command = std::process::Command::new(exe);
    if args.spawn_proxy {
        let database = match &args.database_url {
            Some(url) => url.clone(),
            None => format!("sqlite://{}", dir.path().join("penmesh.db").display()),
        };
        let per_session = plan.clients.div_ceil(plan.sessions).max(64);
        let idle = (plan.duration_s + plan.drain_s as f64 + 60.0).ceil() as u64;
        command
            .arg("serve-proxy")
            .args(["--host", "127.0.0.1", "--port", &port.to_string()])
            .args(["--database-url", &database])
            .args(["--max-connections-per-session", &per_session.to_string()])
            // One address creates every session and opens every connection of the run.
            .args(["--session-rate-per-minute", "0"])
            .args(["--max-connections-per-address", "0"])
            .args(["--max-connections", &plan.clients.saturating_add(64).max(10_000).to_string()])
            .args(["--idle-timeout-secs", &idle.to_string()])
            .args(&args.proxy_arg);
    } else {
        command
            .arg("ceiling")
            .args(["--host", "127.0.0.1", "--port", &port.to_string()])
            .args(&args.ceiling_arg);
    }
    let log = fs_err::File::create(dir.path().join("server.log"))?.into_parts().0;
    command
        .env("RUST_LOG", std::env::var("RUST_LOG").unwrap_or_else(|_| "warn".into()))
        .env_remove("PORT")
        .stdin(std::process::Stdio::null())
        .stdout(std::process::Stdio::null())
        .stderr(log);
    let child = command.spawn().context("cannot start the server")?;
    let mut spawned = Spawned { child, dir };
    let base = format!("http://127.0.0.1:{port}");
    let deadline = std::time::Instant::now() + Duration::from_secs(60);
    loop {
        if std::net::TcpStream::connect(("127.0.0.1", port)).is_ok() {
            return Ok((base, spawned));
        }
        if let Ok(Some(status)) = spawned.child.try_wait() {
            let log =
                std::fs::read_to_string(spawned.dir.path().join("server.log")).unwrap_or_default();
            anyhow::bail!("the server exited at start ({status}): {}", log.trim());
        }
        anyhow::ensure!(
            std::time::Instant::now() < deadline,
            "the server did not listen within 60 s"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
}
