//! Settings: command-line flags, environment variables and an optional TOML or JSON file.
//!
//! Precedence, highest first: a flag, its environment variable, the `--config` file, the
//! default. Every setting is documented by `penmesh-proxy --help` with its default.

use std::path::{Path, PathBuf};

use anyhow::Context;
use clap::parser::ValueSource;
use clap::{ArgMatches, CommandFactory, FromArgMatches, Parser, ValueEnum};
use serde::{Deserialize, Serialize};

/// How SQLite syncs to disk (see `docs/storage.md` for what each survives).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum SqliteSync {
    /// WAL + `synchronous=NORMAL`: survives a killed process, not a power cut.
    Normal,
    /// WAL + `synchronous=FULL`: survives a power cut too, at the cost of an fsync per commit.
    Full,
}

/// A SQLite page size: a power of two from 512 to 65536, as SQLite takes.
fn page_size(text: &str) -> Result<u32, String> {
    let size: u32 = text.parse().map_err(|_| format!("{text:?} is not a number of bytes"))?;
    if size.is_power_of_two() && (512..=65536).contains(&size) {
        Ok(size)
    } else {
        Err(format!("{size} is not a power of two from 512 to 65536"))
    }
}

/// A database URL whose password never reaches a log or an error message: `Display` and
/// `Debug` show it with the password (of the user info, or a `password` parameter) as `***`;
/// [`DatabaseUrl::expose`] gives the whole URL to the code that connects.
///
/// Not `secrecy::SecretString`: that one hides the host and the database too, which an operator
/// needs to read in the logs, and it cannot be serialised, which merging the config file needs.
#[derive(Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(transparent)]
pub struct DatabaseUrl(String);

impl DatabaseUrl {
    /// The whole URL, password included: only for connecting.
    pub fn expose(&self) -> &str {
        &self.0
    }
}

impl From<String> for DatabaseUrl {
    fn from(url: String) -> DatabaseUrl {
        DatabaseUrl(url)
    }
}

impl std::str::FromStr for DatabaseUrl {
    type Err = std::convert::Infallible;

    fn from_str(url: &str) -> Result<DatabaseUrl, Self::Err> {
        Ok(DatabaseUrl(url.to_string()))
    }
}

impl std::fmt::Display for DatabaseUrl {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let Ok(mut url) = url::Url::parse(self.0.trim()) else {
            // Where a password would be is unknown: say only what kind of URL it is.
            let scheme = self.0.split_once(':').map_or("", |(scheme, _)| scheme);
            return write!(f, "({scheme}: URL that cannot be parsed)");
        };
        if url.password().is_some() {
            let _ = url.set_password(Some("***"));
        }
        if url.query_pairs().any(|(key, _)| key == "password") {
            let pairs: Vec<(String, String)> = url
                .query_pairs()
                .map(|(key, value)| {
                    let value = if key == "password" { "***".into() } else { value.into_owned() };
                    (key.into_owned(), value)
                })
                .collect();
            url.query_pairs_mut().clear().extend_pairs(pairs);
        }
        f.write_str(url.as_str())
    }
}

impl std::fmt::Debug for DatabaseUrl {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "DatabaseUrl({self})")
    }
}

/// Every setting of the proxy.
#[derive(Debug, Clone, Parser, Serialize, Deserialize)]
#[command(name = "penmesh-proxy", version, about = "penmesh simplification proxy")]
pub struct Config {
    /// Optional settings file (TOML, or JSON when the name ends in .json); keys are the long
    /// flag names with `_` or `-`. Flags and environment variables win over the file.
    #[arg(long, env = "PENMESH_CONFIG")]
    #[serde(skip)]
    pub config: Option<PathBuf>,

    /// Address to listen on.
    #[arg(long, env = "PENMESH_HOST", default_value = "0.0.0.0")]
    pub host: String,

    /// Port to listen on (0 picks a free one). `PORT` is honoured, as container platforms set it.
    #[arg(long, env = "PORT", default_value_t = 8080)]
    pub port: u16,

    /// Database: `sqlite://PATH` (file created if missing) or `postgres://USER@HOST/DB`.
    #[arg(long, env = "PENMESH_DATABASE_URL", default_value = "sqlite://penmesh.db")]
    pub database_url: DatabaseUrl,

    /// PostgreSQL only: the URL of the connections that need a session of their own: the
    /// session-event listener (`LISTEN`), the stroke locks and the migrations (session-level
    /// advisory locks). Set it to the server itself when `database_url` goes through a pooler
    /// in transaction mode (PgBouncer), which breaks all three. Default: `database_url`.
    #[arg(long, env = "PENMESH_DIRECT_DATABASE_URL")]
    pub direct_database_url: Option<DatabaseUrl>,

    /// SQLite durability: `normal` (survives a killed process) or `full` (also a power cut).
    #[arg(long, env = "PENMESH_SQLITE_SYNCHRONOUS", value_enum, default_value_t = SqliteSync::Normal)]
    pub sqlite_synchronous: SqliteSync,

    /// SQLite page size in bytes (a power of two, 512 to 65536) of a database this proxy
    /// creates; an existing file keeps its own. Every commit writes whole pages, so small
    /// pages write less per commit (see `docs/storage.md`).
    #[arg(long, env = "PENMESH_SQLITE_PAGE_SIZE", default_value_t = 1024, value_parser = page_size)]
    pub sqlite_page_size: u32,

    /// Database connections for reads and HTTP writes (the group-commit writer has its own).
    #[arg(long, env = "PENMESH_DB_MAX_CONNECTIONS", default_value_t = 8)]
    pub db_max_connections: u32,

    /// How much lower than the group-commit writer's the priority of the threads that serve the
    /// connections is (Linux nice steps, 0 to 19; 0: the same). Past the knee every connection
    /// waits for the writer, so the writer should get the CPU first (see docs/performance-log.md).
    #[arg(long, env = "PENMESH_WORKER_NICE", default_value_t = 10, value_parser = clap::value_parser!(i32).range(0..=19))]
    pub worker_nice: i32,

    /// Count the time spent in each stage of the ingest path, read at `/metrics` as
    /// `penmesh_stage_nanoseconds_total{stage}` (`proxy/src/stages.rs`, docs/performance.md).
    /// Off: one relaxed atomic load per stage; on: two clock reads per poll.
    #[arg(long, env = "PENMESH_STAGE_TIMING")]
    pub stage_timing: bool,

    /// Group commit: at most one commit per this many milliseconds (0: commit as soon as the
    /// previous commit is done).
    #[arg(long, env = "PENMESH_COMMIT_INTERVAL_MS", default_value_t = 2)]
    pub commit_interval_ms: u64,

    /// Group commit: most write requests in one transaction.
    #[arg(long, env = "PENMESH_COMMIT_MAX_REQUESTS", default_value_t = 4096)]
    pub commit_max_requests: usize,

    /// Capacity of the queue into the writer (connections wait when it is full).
    #[arg(long, env = "PENMESH_WRITER_QUEUE", default_value_t = 16384)]
    pub writer_queue: usize,

    /// Largest WebSocket message (bytes) that is decoded; larger ones get `frame_too_large`.
    #[arg(long, env = "PENMESH_MAX_MESSAGE_BYTES", default_value_t = 256 * 1024)]
    pub max_message_bytes: usize,

    /// Hard limit on a WebSocket message (bytes): past it the connection is closed (1009).
    /// 0 means four times `max_message_bytes`.
    #[arg(long, env = "PENMESH_HARD_MESSAGE_BYTES", default_value_t = 0)]
    pub hard_message_bytes: usize,

    /// Most samples in one `Points` batch.
    #[arg(long, env = "PENMESH_MAX_BATCH_SAMPLES", default_value_t = 4096)]
    pub max_batch_samples: usize,

    /// Most samples in one stroke.
    #[arg(long, env = "PENMESH_MAX_STROKE_SAMPLES", default_value_t = 1_000_000)]
    pub max_stroke_samples: u64,

    /// Most strokes open at once on one connection.
    #[arg(long, env = "PENMESH_MAX_OPEN_STROKES", default_value_t = 16)]
    pub max_open_strokes: usize,

    /// Most WebSocket connections at once per session.
    #[arg(long, env = "PENMESH_MAX_CONNECTIONS_PER_SESSION", default_value_t = 64)]
    pub max_connections_per_session: usize,

    /// Most WebSocket connections at once on this replica; past it an upgrade gets 503.
    #[arg(long, env = "PENMESH_MAX_CONNECTIONS", default_value_t = 10_000)]
    pub max_connections: usize,

    /// Most WebSocket connections at once from one client address on this replica (the address
    /// of `session_rate_per_minute`: the peer, or the trusted `X-Forwarded-For`); past it an
    /// upgrade gets 503. 0: no limit (where the client's address cannot be known).
    #[arg(long, env = "PENMESH_MAX_CONNECTIONS_PER_ADDRESS", default_value_t = 100)]
    pub max_connections_per_address: usize,

    /// A WebSocket connection that has not sent `Hello` this many seconds after the upgrade is
    /// closed.
    #[arg(long, env = "PENMESH_HELLO_TIMEOUT_SECS", default_value_t = 10)]
    pub hello_timeout_secs: u64,

    /// An HTTP connection that has not sent a whole request head (request line and headers)
    /// this many seconds after it opened, or after its previous request, is closed (slowloris).
    #[arg(long, env = "PENMESH_HEADER_TIMEOUT_SECS", default_value_t = 10)]
    pub header_timeout_secs: u64,

    /// An HTTP request (not the WebSocket) not answered within this many seconds, its body
    /// included, gets 408.
    #[arg(long, env = "PENMESH_REQUEST_TIMEOUT_SECS", default_value_t = 30)]
    pub request_timeout_secs: u64,

    /// Sessions one client address may create per minute (`POST /v1/sessions`), after a burst
    /// of `session_burst`; past it, 429 with `Retry-After`. 0: no limit.
    #[arg(long, env = "PENMESH_SESSION_RATE_PER_MINUTE", default_value_t = 30)]
    pub session_rate_per_minute: u32,

    /// Sessions one client address may create at once before `session_rate_per_minute` applies.
    #[arg(long, env = "PENMESH_SESSION_BURST", default_value_t = 10)]
    pub session_burst: u32,

    /// Moves one participant may make a second (a stroke placed anew: `set_placement`, `PUT
    /// /v1/strokes/{id}/placement`), after a burst of `move_burst`. Past it, HTTP answers 429
    /// with `Retry-After` and the WebSocket connection waits its turn (reading nothing
    /// meanwhile). 0: no limit.
    #[arg(long, env = "PENMESH_MOVE_RATE_PER_SECOND", default_value_t = 200)]
    pub move_rate_per_second: u32,

    /// Moves one participant may make at once before `move_rate_per_second` applies (the page
    /// sends one per selected stroke when a drag, a nudge or an undo ends).
    #[arg(long, env = "PENMESH_MOVE_BURST", default_value_t = 2000)]
    pub move_burst: u32,

    /// Solid changes one participant may make a second (`set_solid`, `PUT
    /// /v1/strokes/{id}/solid`: each builds a mesh), after a burst of `solid_burst`; past it as
    /// for moves. 0: no limit.
    #[arg(long, env = "PENMESH_SOLID_RATE_PER_SECOND", default_value_t = 10)]
    pub solid_rate_per_second: u32,

    /// Solid changes one participant may make at once before `solid_rate_per_second` applies.
    #[arg(long, env = "PENMESH_SOLID_BURST", default_value_t = 100)]
    pub solid_burst: u32,

    /// Retained samples a session's duplicates may tell its watchers a second (each watcher
    /// is sent a duplicate with its source's retained samples), after a burst of what one
    /// watcher's event queue holds (`outgoing_queue_bytes` of samples); past it a duplicate
    /// gets 429 with `Retry-After`. 0: no limit.
    #[arg(long, env = "PENMESH_DUPLICATE_SAMPLES_PER_SECOND", default_value_t = 32_768)]
    pub duplicate_samples_per_second: u32,

    /// Take the client address from `X-Forwarded-For` / `X-Real-IP` / `Forwarded` (only
    /// behind a proxy that sets them; otherwise a client can claim any address). Off: the
    /// peer's address, which behind a proxy is the proxy's.
    #[arg(long, env = "PENMESH_TRUST_FORWARDED_FOR", default_value_t = false,
          action = clap::ArgAction::Set, num_args = 0..=1, default_missing_value = "true")]
    pub trust_forwarded_for: bool,

    /// Longest `device` of a `StrokeBegin` (characters).
    #[arg(long, env = "PENMESH_MAX_DEVICE_CHARS", default_value_t = 200)]
    pub max_device_chars: usize,

    /// Most retained (simplified) samples one open stroke holds in memory; past it the batch
    /// is refused with `stroke_too_long` (a tolerance near 0 retains every sample).
    #[arg(long, env = "PENMESH_MAX_STROKE_RETAINED", default_value_t = 20_000)]
    pub max_stroke_retained: usize,

    /// Bytes of samples queued into the writer at once (connections wait past it), next to
    /// the count limit `writer_queue`.
    #[arg(long, env = "PENMESH_WRITER_QUEUE_BYTES", default_value_t = 64 * 1024 * 1024)]
    pub writer_queue_bytes: usize,

    /// A connection that does no work for this many seconds is closed: only a `Hello`,
    /// `StrokeBegin`, `Points` or `StrokeEnd` the proxy carries out counts, not a `Ping`
    /// message nor a WebSocket ping or pong (those keep the heartbeat's peer alive, not its
    /// slot).
    #[arg(long, env = "PENMESH_IDLE_TIMEOUT_SECS", default_value_t = 300)]
    pub idle_timeout_secs: u64,

    /// A connection heard nothing from (not even a pong) for this long is pinged, and after
    /// three such periods it is taken for gone and its strokes are let go (ms).
    #[arg(long, env = "PENMESH_HEARTBEAT_MS", default_value_t = 5000)]
    pub heartbeat_ms: u64,

    /// Largest HTTP request body (bytes), e.g. a GLB mesh upload.
    #[arg(long, env = "PENMESH_MAX_BODY_BYTES", default_value_t = 16 * 1024 * 1024)]
    pub max_body_bytes: usize,

    /// Large HTTP bodies (over 1 MiB: the raw samples of a long stroke, a large mesh, sent or
    /// received) handled at once on this replica; past it such a request gets 503 with
    /// `Retry-After`.
    #[arg(long, env = "PENMESH_MAX_LARGE_BODIES", default_value_t = 4)]
    pub max_large_bodies: usize,

    /// Most bytes of meshes one session may store; an upload past it gets 413
    /// `quota_exceeded`.
    #[arg(long, env = "PENMESH_MAX_SESSION_MESH_BYTES", default_value_t = 256 * 1024 * 1024)]
    pub max_session_mesh_bytes: u64,

    /// Most samples one session's strokes may store for a duplicate or an import to be made
    /// (drawn samples count toward it; a copy past it gets 413 `quota_exceeded`).
    #[arg(long, env = "PENMESH_MAX_SESSION_SAMPLES", default_value_t = 50_000_000)]
    pub max_session_samples: u64,

    /// Long unfinished strokes (2048 stored samples or more) replayed at once on this replica
    /// to rebuild what ACUTS retained (a session's history, a resume); more wait their turn.
    #[arg(long, env = "PENMESH_MAX_REPLAYS", default_value_t = 2)]
    pub max_replays: usize,

    /// Outgoing messages queued per connection; a reader slower than this is disconnected.
    #[arg(long, env = "PENMESH_OUTGOING_QUEUE", default_value_t = 1024)]
    pub outgoing_queue: usize,

    /// Bytes of outgoing messages queued per connection, next to the count `outgoing_queue`
    /// (a message enters while fewer are queued, so at most this plus one message); the
    /// session's events waiting for the connection are bounded by as many bytes of samples.
    #[arg(long, env = "PENMESH_OUTGOING_QUEUE_BYTES", default_value_t = 1024 * 1024)]
    pub outgoing_queue_bytes: usize,

    /// A connection whose outgoing queue stays full for this long (ms) while answers wait is a
    /// slow reader, and is disconnected (a full queue alone is not: a group commit can
    /// acknowledge many batches at once).
    #[arg(long, env = "PENMESH_SLOW_READER_MS", default_value_t = 1000)]
    pub slow_reader_ms: u64,

    /// Batches per connection accepted but not yet committed; reading pauses past it.
    #[arg(long, env = "PENMESH_MAX_INFLIGHT", default_value_t = 64)]
    pub max_inflight: usize,

    /// Most frames a connection reads in one wake-up; the `points` batches of one stroke among
    /// them go to the writer as one request, answered by one `ack` (1: each frame alone).
    #[arg(long, env = "PENMESH_GATHER_FRAMES", default_value_t = 16, value_parser = clap::value_parser!(u64).range(1..=1024))]
    pub gather_frames: u64,

    /// How long a resumed stroke waits for the connection that still holds it to let go (ms).
    #[arg(long, env = "PENMESH_CLAIM_WAIT_MS", default_value_t = 2000)]
    pub claim_wait_ms: u64,

    /// Longest a database round trip may take (ms) before its connection is given up as dead:
    /// a network partition leaves a socket silent and nothing else ends the wait. It bounds the
    /// writer's transaction (its requests fail, the clients resume from their last ack), the
    /// stroke locks' queries, taking a connection from the pool and (re)connecting the listener.
    #[arg(long, env = "PENMESH_DB_TIMEOUT_MS", default_value_t = 10_000)]
    pub db_timeout_ms: u64,

    /// PostgreSQL: every this many ms the session-event listener notifies itself on its own
    /// connection; a heartbeat not back within as long again means that connection is lost
    /// (events are being missed): it listens on a new one and resyncs every local session.
    #[arg(long, env = "PENMESH_LISTENER_HEARTBEAT_MS", default_value_t = 5_000)]
    pub listener_heartbeat_ms: u64,

    /// Seconds granted on shutdown to flush open strokes and close every socket.
    #[arg(long, env = "PENMESH_SHUTDOWN_GRACE_SECS", default_value_t = 10)]
    pub shutdown_grace_secs: u64,

    /// Default ACUTS chord-height tolerance `d_d` when `StrokeBegin` has no params.
    #[arg(long, env = "PENMESH_TOLERANCE", default_value_t = penmesh::DEFAULT_TOLERANCE)]
    pub tolerance: f64,

    /// Default ACUTS angle threshold `d_alpha` (degrees).
    #[arg(long, env = "PENMESH_ANGLE_DEG", default_value_t = penmesh::DEFAULT_ANGLE_DEG)]
    pub angle_deg: f64,

    /// Default ACUTS pressure tolerance `delta_p` (the interpolation gate); the paper's variance
    /// gate is a per-stroke choice in `StrokeBegin`'s params.
    #[arg(long, env = "PENMESH_PRESSURE_TOLERANCE", default_value_t = penmesh::DEFAULT_PRESSURE_TOLERANCE)]
    pub pressure_tolerance: f64,
}

impl Config {
    /// Parses flags and environment, then fills what neither gave from the `--config` file.
    /// Exits with clap's message on `--help`, `--version` or a bad flag.
    pub fn load() -> anyhow::Result<Config> {
        let matches = Config::command().get_matches();
        let config = Config::from_arg_matches(&matches).unwrap_or_else(|e| e.exit());
        match config.config.clone() {
            Some(path) => config.merge_file(&path, &matches),
            None => Ok(config),
        }
    }

    pub fn load_from<I, T>(args: I) -> anyhow::Result<Config>
    where
        I: IntoIterator<Item = T>,
        T: Into<std::ffi::OsString> + Clone,
    {
        let matches = Config::command().try_get_matches_from(args)?;
        let config = Config::from_arg_matches(&matches)?;
        match config.config.clone() {
            Some(path) => config.merge_file(&path, &matches),
            None => Ok(config),
        }
    }

    fn merge_file(self, path: &Path, matches: &ArgMatches) -> anyhow::Result<Config> {
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("reading config file {}", path.display()))?;
        let file: serde_json::Map<String, serde_json::Value> =
            if path.extension().is_some_and(|e| e == "json") {
                serde_json::from_str(&text)
                    .with_context(|| format!("parsing JSON config {}", path.display()))?
            } else {
                toml::from_str(&text)
                    .with_context(|| format!("parsing TOML config {}", path.display()))?
            };
        let serde_json::Value::Object(mut merged) = serde_json::to_value(&self)? else {
            unreachable!("Config serialises to an object");
        };
        for (key, value) in file {
            let key = key.replace('-', "_");
            if !merged.contains_key(&key) {
                anyhow::bail!("config file {}: unknown setting `{key}`", path.display());
            }
            if matches.value_source(&key) == Some(ValueSource::DefaultValue) {
                merged.insert(key, value);
            }
        }
        let mut config: Config = serde_json::from_value(serde_json::Value::Object(merged))
            .with_context(|| format!("config file {}", path.display()))?;
        config.config = Some(path.to_path_buf());
        Ok(config)
    }

    /// The defaults, ignoring flags and the environment (for tests and embedding).
    pub fn defaults() -> Config {
        let matches =
            Config::command().mut_args(|a| a.env(None::<&str>)).get_matches_from(["penmesh-proxy"]);
        Config::from_arg_matches(&matches).expect("defaults parse")
    }

    /// Refuses settings that cannot work, naming the setting, so that a bad value stops the
    /// proxy at start-up instead of refusing every stroke later.
    pub fn check(&self) -> anyhow::Result<()> {
        // A zero period or deadline would time out every wait, or ping without pause; no
        // permit at all would refuse every large body, or make every long replay wait forever.
        for (value, setting) in [
            (self.heartbeat_ms, "--heartbeat-ms (PENMESH_HEARTBEAT_MS)"),
            (self.hello_timeout_secs, "--hello-timeout-secs (PENMESH_HELLO_TIMEOUT_SECS)"),
            (self.idle_timeout_secs, "--idle-timeout-secs (PENMESH_IDLE_TIMEOUT_SECS)"),
            (self.db_timeout_ms, "--db-timeout-ms (PENMESH_DB_TIMEOUT_MS)"),
            (self.listener_heartbeat_ms, "--listener-heartbeat-ms (PENMESH_LISTENER_HEARTBEAT_MS)"),
            (self.header_timeout_secs, "--header-timeout-secs (PENMESH_HEADER_TIMEOUT_SECS)"),
            (self.request_timeout_secs, "--request-timeout-secs (PENMESH_REQUEST_TIMEOUT_SECS)"),
            (self.max_large_bodies as u64, "--max-large-bodies (PENMESH_MAX_LARGE_BODIES)"),
            (self.max_replays as u64, "--max-replays (PENMESH_MAX_REPLAYS)"),
            (self.move_burst.into(), "--move-burst (PENMESH_MOVE_BURST)"),
            (self.solid_burst.into(), "--solid-burst (PENMESH_SOLID_BURST)"),
        ] {
            anyhow::ensure!(value > 0, "bad setting {setting}: must be above 0");
        }
        let params = self.default_params();
        params.validate().map_err(|e| {
            let setting = match e.name {
                "tolerance" => "--tolerance (PENMESH_TOLERANCE)",
                "angle_deg" => "--angle-deg (PENMESH_ANGLE_DEG)",
                _ => "--pressure-tolerance (PENMESH_PRESSURE_TOLERANCE)",
            };
            anyhow::anyhow!("bad setting {setting}: {e}")
        })
    }

    /// The ACUTS parameters of a stroke whose `StrokeBegin` names none ([`Config::check`]
    /// refuses them at start-up when they are out of range).
    pub fn default_params(&self) -> penmesh::AcutsParams {
        penmesh::AcutsParams {
            tolerance: self.tolerance,
            angle_deg: self.angle_deg,
            pressure: penmesh::PressureGate::Interpolation(self.pressure_tolerance),
            ..penmesh::AcutsParams::default()
        }
    }

    /// Where the listener, the lock connection and the migrations go (`direct_database_url`).
    pub fn direct_database_url(&self) -> &DatabaseUrl {
        self.direct_database_url.as_ref().unwrap_or(&self.database_url)
    }

    pub fn hard_message_limit(&self) -> usize {
        if self.hard_message_bytes == 0 {
            self.max_message_bytes.saturating_mul(4)
        } else {
            self.hard_message_bytes.max(self.max_message_bytes)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Loads settings from `args` with no environment variable seen, as on a clean machine.
    fn load_without_env(args: &[&str]) -> anyhow::Result<Config> {
        let matches = Config::command()
            .mut_args(|a| a.env(None::<&str>))
            .try_get_matches_from(args.iter().copied())?;
        let config = Config::from_arg_matches(&matches)?;
        match config.config.clone() {
            Some(path) => config.merge_file(&path, &matches),
            None => Ok(config),
        }
    }

    #[test]
    fn file_fills_what_flags_do_not_give() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("proxy.toml");
        std::fs::write(&path, "port = 9000\nmax-open-strokes = 3\n").unwrap();
        let config = load_without_env(&[
            "penmesh-proxy",
            "--config",
            path.to_str().unwrap(),
            "--max-open-strokes",
            "5",
        ])
        .unwrap();
        assert_eq!(config.max_open_strokes, 5, "a flag wins over the file");
        assert_eq!(config.port, 9000, "the file fills what no flag gave");
    }

    #[test]
    fn unknown_file_setting_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("proxy.json");
        std::fs::write(&path, r#"{"prot": 1}"#).unwrap();
        let err =
            Config::load_from(["penmesh-proxy", "--config", path.to_str().unwrap()]).unwrap_err();
        assert!(err.to_string().contains("prot"), "{err}");
    }

    #[test]
    fn direct_database_url_defaults_to_the_main_one() {
        let main = "postgres://app@pooler:6432/penmesh";
        let config = load_without_env(&["penmesh-proxy", "--database-url", main]).unwrap();
        assert_eq!(config.direct_database_url().expose(), main);
        let direct = "postgres://app@db:5432/penmesh";
        let config = load_without_env(&[
            "penmesh-proxy",
            "--database-url",
            main,
            "--direct-database-url",
            direct,
        ])
        .unwrap();
        assert_eq!(config.direct_database_url().expose(), direct);
        assert_eq!(config.database_url.expose(), main);
    }

    #[test]
    fn a_database_url_never_shows_its_password() {
        let cases = [
            ("postgres://u:secret@h/db", "postgres://u:***@h/db"),
            (
                "postgres://u@h/db?sslmode=require&password=secret",
                "postgres://u@h/db?sslmode=require&password=***",
            ),
            (
                "postgresql://u:p%40ss@h:5433/db?application_name=x",
                "postgresql://u:***@h:5433/db?application_name=x",
            ),
            ("sqlite://penmesh.db", "sqlite://penmesh.db"),
            ("postgres://u:secret@[::1", "(postgres: URL that cannot be parsed)"),
        ];
        for (url, shown) in cases {
            let url: DatabaseUrl = url.parse().unwrap();
            assert_eq!(url.to_string(), shown);
            assert_eq!(format!("{url:?}"), format!("DatabaseUrl({shown})"));
            let config = Config { database_url: url, ..Config::defaults() };
            assert!(!format!("{config:?}").contains("secret"), "{config:?}");
        }
    }

    #[test]
    fn help_documents_every_setting_with_its_default_and_variable() {
        let mut command = Config::command();
        let help = command.render_long_help().to_string();
        for arg in command.get_arguments() {
            let id = arg.get_id().as_str();
            if matches!(id, "help" | "version") {
                continue;
            }
            let long = arg.get_long().unwrap_or_else(|| panic!("setting {id} has no flag"));
            assert!(help.contains(&format!("--{long}")), "help lacks --{long}");
            assert!(arg.get_help().is_some(), "--{long} has no help text");
            if id != "config" {
                let env = arg.get_env().unwrap_or_else(|| panic!("--{long} has no variable"));
                assert!(help.contains(env.to_str().unwrap()), "help lacks {env:?}");
            }
            for default in arg.get_default_values() {
                assert!(
                    help.contains(&format!("default: {}", default.to_str().unwrap())),
                    "help lacks --{long}'s default {default:?}"
                );
            }
        }
    }

    #[test]
    fn out_of_range_acuts_defaults_are_refused_at_start_up() {
        for (flag, value, named) in [
            ("--tolerance", "-1", "PENMESH_TOLERANCE"),
            ("--tolerance", "NaN", "PENMESH_TOLERANCE"),
            ("--angle-deg", "91", "PENMESH_ANGLE_DEG"),
            ("--pressure-tolerance", "-0.5", "PENMESH_PRESSURE_TOLERANCE"),
            ("--heartbeat-ms", "0", "PENMESH_HEARTBEAT_MS"),
            ("--hello-timeout-secs", "0", "PENMESH_HELLO_TIMEOUT_SECS"),
            ("--idle-timeout-secs", "0", "PENMESH_IDLE_TIMEOUT_SECS"),
            ("--db-timeout-ms", "0", "PENMESH_DB_TIMEOUT_MS"),
            ("--listener-heartbeat-ms", "0", "PENMESH_LISTENER_HEARTBEAT_MS"),
            ("--header-timeout-secs", "0", "PENMESH_HEADER_TIMEOUT_SECS"),
            ("--request-timeout-secs", "0", "PENMESH_REQUEST_TIMEOUT_SECS"),
            ("--max-large-bodies", "0", "PENMESH_MAX_LARGE_BODIES"),
            ("--max-replays", "0", "PENMESH_MAX_REPLAYS"),
        ] {
            let setting = format!("{flag}={value}");
            let config = load_without_env(&["penmesh-proxy", &setting]).unwrap();
            let err = config.check().unwrap_err().to_string();
            assert!(err.contains(named), "{flag} {value}: {err}");
        }
        assert!(Config::defaults().check().is_ok());
    }

    #[test]
    fn a_sqlite_page_size_sqlite_cannot_take_is_refused() {
        for bad in ["3000", "256", "131072", "1k"] {
            let setting = format!("--sqlite-page-size={bad}");
            let err = load_without_env(&["penmesh-proxy", &setting]).unwrap_err().to_string();
            assert!(err.contains("--sqlite-page-size"), "{bad}: {err}");
        }
        let config = load_without_env(&["penmesh-proxy", "--sqlite-page-size=4096"]).unwrap();
        assert_eq!(config.sqlite_page_size, 4096);
        assert_eq!(Config::defaults().sqlite_page_size, 1024);
    }
}
