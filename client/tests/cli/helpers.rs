//! Running the binary, a proxy, and reading the database it leaves behind (`support/stored.rs`,
//! shared with the lab's tests).

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};

use penmesh::protocol::quantize_sample;
use penmesh::{Sample, Stroke};
use serde_json::Value;

// Each test crate that includes it reads a part of what it holds.
#[allow(dead_code)]
#[path = "../support/stored.rs"]
mod stored;
pub use stored::{assert_stored_complete, stored_strokes};

/// How long any single wait may take.
pub const TIMEOUT: Duration = Duration::from_secs(60);

pub fn penmesh() -> Command {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_penmesh"));
    cmd.env_remove("RUST_LOG")
        .env_remove("PENMESH_SERVER")
        .env_remove("PENMESH_SESSION")
        .env_remove("PENMESH_TOKEN");
    cmd
}

/// Runs to the end with a time limit.
pub fn run(cmd: &mut Command) -> Output {
    let child = cmd.stdout(Stdio::piped()).stderr(Stdio::piped()).spawn().expect("spawn penmesh");
    wait(child)
}

pub fn wait(mut child: Child) -> Output {
    let started = Instant::now();
    loop {
        if child.try_wait().expect("wait").is_some() {
            return child.wait_with_output().expect("output");
        }
        if started.elapsed() > TIMEOUT {
            let _ = child.kill();
            let out = child.wait_with_output().expect("output");
            panic!(
                "penmesh did not finish in {TIMEOUT:?}; stderr: {}",
                String::from_utf8_lossy(&out.stderr)
            );
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// Parses the one JSON object a `--json` run prints, failing with its stderr otherwise.
pub fn json_of(out: &Output) -> Value {
    assert!(
        out.status.success(),
        "penmesh failed ({}): {}",
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap_or_else(|e| {
        panic!("stdout is not one JSON object ({e}): {}", String::from_utf8_lossy(&out.stdout))
    })
}

/// A proxy serving one session on the SQLite file `db`: the proxy's own `Application`, in a
/// thread and runtime of its own, so that [`Proxy::kill`] stops it at once, with no wind-down
/// (its sockets and database connections close as in a crash). The user's CLI does not link
/// the server; its tests do.
pub struct Proxy {
    stop: Option<std::sync::mpsc::Sender<()>>,
    thread: Option<std::thread::JoinHandle<()>>,
    pub url: String,
    pub session: String,
    pub token: String,
    pub port: u16,
    pub db: PathBuf,
}

impl Proxy {
    /// Starts a proxy on `port` (0: any) with the database `db`, and makes a session.
    pub fn start(db: &Path, port: u16) -> Proxy {
        let mut config = penmesh_proxy::Config::defaults();
        config.host = "127.0.0.1".into();
        config.port = port;
        config.database_url = format!("sqlite://{}", db.display()).into();
        config.shutdown_grace_secs = 1;
        let (started, ready) = std::sync::mpsc::channel();
        let (stop, stopped) = std::sync::mpsc::channel::<()>();
        let thread = std::thread::spawn(move || {
            let runtime = tokio::runtime::Builder::new_multi_thread()
                .worker_threads(2)
                .enable_all()
                .build()
                .expect("a runtime for the proxy");
            let session = runtime.block_on(async {
                let app =
                    penmesh_proxy::Application::build(config).await.expect("the proxy starts");
                let url = format!("http://127.0.0.1:{}", app.port());
                tokio::spawn(app.run_until_stopped());
                let created: Value = reqwest::Client::new()
                    .post(format!("{url}/v1/sessions"))
                    .send()
                    .await
                    .and_then(reqwest::Response::error_for_status)
                    .expect("POST /v1/sessions")
                    .json()
                    .await
                    .expect("a new session");
                (url, created)
            });
            started.send(session).expect("the test waits");
            let _ = stopped.recv();
            runtime.shutdown_background();
        });
        let (url, created) = ready.recv_timeout(TIMEOUT).expect("the proxy started");
        let port = url.rsplit(':').next().unwrap().parse().unwrap();
        Proxy {
            stop: Some(stop),
            thread: Some(thread),
            session: created["session"].as_str().unwrap().to_string(),
            token: created["token"].as_str().unwrap().to_string(),
            url,
            port,
            db: db.to_path_buf(),
        }
    }

    /// `penmesh draw` into this proxy's session.
    pub fn draw(&self) -> Command {
        let mut cmd = penmesh();
        cmd.args(["draw", "--json", "--server", &self.url, "--session", &self.session])
            .args(["--token", &self.token]);
        cmd
    }

    /// Stops the proxy at once, as a crash or `kill -9` would.
    pub fn kill(&mut self) {
        drop(self.stop.take());
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}

impl Drop for Proxy {
    fn drop(&mut self) {
        self.kill();
    }
}

/// What the client streams for a drawn stroke: times from pen-down, snapped to the codec's
/// grid, then stage-1 resampled with the default distance.
pub fn expected_resampled(stroke: &[Sample]) -> Vec<Sample> {
    let t0 = stroke[0].t;
    let mut drawn: Vec<Sample> = Vec::new();
    for s in stroke {
        let mut q = quantize_sample(&Sample { t: s.t - t0, ..*s });
        if let Some(prev) = drawn.last() {
            q.t = q.t.max(prev.t);
        }
        drawn.push(q);
    }
    penmesh::resample(&drawn, penmesh::DEFAULT_RESAMPLE_DISTANCE)
        .into_iter()
        .map(|i| drawn[i])
        .collect()
}

/// The generated stroke `penmesh draw --synth` draws with these settings.
pub fn synth(shape: penmesh::Shape, speed: f64, size: f64, seed: u64) -> Stroke {
    penmesh::generate_stroke(&penmesh::GeneratorParams {
        shape,
        speed,
        size,
        rate_hz: penmesh::DEFAULT_SAMPLE_RATE_HZ,
        seed,
    })
    .unwrap()
}
