//! Running the binary, a proxy process, and reading the database it leaves behind.

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};

use penmesh::protocol::quantize_sample;
use penmesh::{Sample, Stroke};
use serde_json::Value;
use sqlx::Row;

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

/// A proxy process serving one session (`penmesh demo --people 0 --keep-serving`).
pub struct Proxy {
    child: Child,
    pub url: String,
    pub session: String,
    pub token: String,
    pub port: u16,
    pub db: PathBuf,
}

impl Proxy {
    /// Starts a proxy on `port` (0: any) with the database `db`.
    pub fn start(db: &Path, port: u16) -> Proxy {
        let mut child = penmesh()
            .args(["demo", "--people", "0", "--keep-serving", "--json", "--port"])
            .arg(port.to_string())
            .arg("--db")
            .arg(db)
            .arg("--out")
            .arg(db.with_extension("out"))
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .expect("spawn the proxy");
        let mut line = String::new();
        BufReader::new(child.stdout.take().unwrap()).read_line(&mut line).expect("read proxy line");
        let info: Value = serde_json::from_str(&line)
            .unwrap_or_else(|e| panic!("the proxy printed {line:?}: {e}"));
        let url = info["proxy"].as_str().unwrap().to_string();
        let port = url.rsplit(':').next().unwrap().parse().unwrap();
        Proxy {
            child,
            url,
            session: info["session"].as_str().unwrap().to_string(),
            token: info["token"].as_str().unwrap().to_string(),
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

    /// Kills the process, as a crash or `kill -9` would.
    pub fn kill(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

impl Drop for Proxy {
    fn drop(&mut self) {
        self.kill();
    }
}

/// One stroke as the database holds it.
#[derive(Debug, Clone)]
pub struct StoredStroke {
    pub id: String,
    pub session: String,
    pub status: String,
    pub n_points: u64,
    pub n_retained: u64,
    /// The raw (resampled) samples, from the stored chunks in seq order.
    pub raw: Vec<Sample>,
    /// `(seq, n)` of each stored chunk.
    pub chunks: Vec<(u64, u64)>,
    /// `(glb length, vertices, triangles)` of the stored mesh.
    pub mesh: Option<(u64, u64, u64)>,
    pub glb: Option<Vec<u8>>,
}

/// Every stroke of the database, oldest first.
pub async fn stored_strokes(db: &Path) -> Vec<StoredStroke> {
    let url = format!("sqlite://{}?mode=ro", db.display());
    let pool = sqlx::SqlitePool::connect(&url).await.expect("open the database");
    let rows = sqlx::query(
        "SELECT id, session_id, status, n_retained FROM strokes ORDER BY created_at, id",
    )
    .fetch_all(&pool)
    .await
    .unwrap();
    let mut strokes = Vec::new();
    for row in rows {
        let id: String = row.get("id");
        let chunks = sqlx::query(
            "SELECT seq, n, layout, data FROM stroke_chunks WHERE stroke_id = ? ORDER BY seq",
        )
        .bind(&id)
        .fetch_all(&pool)
        .await
        .unwrap();
        let mut raw = Vec::new();
        let mut spans = Vec::new();
        for chunk in chunks {
            let data: Vec<u8> = chunk.get("data");
            spans.push((chunk.get::<i64, _>("seq") as u64, chunk.get::<i64, _>("n") as u64));
            // The layout is the store's to know: decode through it.
            let layout: i64 = chunk.get("layout");
            raw.extend(
                penmesh_proxy::decode_stored_samples(layout, &data).expect("a stored chunk"),
            );
        }
        let mesh = sqlx::query("SELECT glb, vertices, triangles FROM meshes WHERE stroke_id = ?")
            .bind(&id)
            .fetch_optional(&pool)
            .await
            .unwrap();
        let glb: Option<Vec<u8>> = mesh.as_ref().map(|m| m.get("glb"));
        strokes.push(StoredStroke {
            session: row.get("session_id"),
            status: row.get("status"),
            // As the proxy counts them: where the last chunk ends.
            n_points: spans.last().map_or(0, |&(seq, n)| seq + n),
            n_retained: row.get::<i64, _>("n_retained") as u64,
            raw,
            chunks: spans,
            mesh: mesh.map(|m| {
                (
                    m.get::<Vec<u8>, _>("glb").len() as u64,
                    m.get::<i64, _>("vertices") as u64,
                    m.get::<i64, _>("triangles") as u64,
                )
            }),
            glb,
            id,
        });
    }
    pool.close().await;
    strokes
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

/// Checks a stroke is stored once, complete, contiguous, done, and with its mesh.
pub fn assert_stored_complete(stored: &StoredStroke) {
    assert_eq!(stored.status, "done", "stroke {}", stored.id);
    assert_eq!(stored.raw.len() as u64, stored.n_points, "stroke {}", stored.id);
    let mut next = 0;
    for &(seq, n) in &stored.chunks {
        assert_eq!(seq, next, "stroke {}: chunks overlap or leave a gap", stored.id);
        next += n;
    }
    assert!(stored.mesh.is_some(), "stroke {} has no mesh", stored.id);
}
