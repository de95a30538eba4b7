//! `penmesh-lab demo`: the whole system in one command. A proxy starts in process on an embedded
//! SQLite file, a session is created, and several simulated people draw at once, each through
//! the real path: the live client, a WebSocket, the proxy's ACUTS and storage, HTTP, LRPDP,
//! GLB upload.

use std::path::{Path, PathBuf};

use anyhow::Context;
use clap::Args;
use indicatif::MultiProgress;
use penmesh::protocol::NewSession;
use penmesh::{GeneratorParams, Shape};
use penmesh_proxy::{Application, Config};
use serde::Serialize;

use penmesh_client::commands::draw::{draw_options, init_tracing, progress_bar, runtime};
use penmesh_client::endpoint::Endpoint;
use penmesh_client::input::{Pacing, PenSource, ReplaySource};
use penmesh_client::live;
use penmesh_client::reconstruct::StrokeReport;
use penmesh_client::report::{self, Totals};

#[derive(Debug, Args)]
pub struct DemoArgs {
    /// The SQLite database file (created if missing). Default: a temporary one, removed on exit.
    #[arg(long, value_name = "PATH")]
    pub db: Option<PathBuf>,
    /// Where to write the GLB files.
    #[arg(long, value_name = "DIR", default_value = "penmesh-demo-out")]
    pub out: PathBuf,
    /// Draw as fast as possible instead of at the people's real pace.
    #[arg(long)]
    pub fast: bool,
    /// Leave the proxy up after the drawing, until Ctrl-C, so other clients can join.
    #[arg(long)]
    pub keep_serving: bool,
    /// How many simulated people draw at once (0 with --keep-serving: only serve).
    #[arg(long, default_value_t = 4)]
    pub people: usize,
    /// Address of the proxy.
    #[arg(long, default_value = "127.0.0.1")]
    pub host: String,
    /// Port of the proxy (0 picks a free one).
    #[arg(long, default_value_t = 0)]
    pub port: u16,
    #[command(flatten)]
    pub live: penmesh_client::commands::draw::LiveArgs,
}

const NAMES: [&str; 8] = ["ada", "grace", "alan", "edsger", "barbara", "donald", "frances", "ken"];

/// The paper's pen speeds (table 4), px/s.
const SPEEDS: [f64; 4] = [200.0, 300.0, 400.0, 500.0];

/// What person `k` draws: the four classic contours and a scribble, at one of the paper's
/// speeds, starting with a different shape than the others.
pub fn plan(k: usize) -> (String, Vec<GeneratorParams>) {
    let name = if k < NAMES.len() {
        NAMES[k].to_string()
    } else {
        format!("{}{}", NAMES[k % NAMES.len()], k / NAMES.len() + 1)
    };
    let n = Shape::ALL.len();
    let strokes = (0..n)
        .map(|j| GeneratorParams {
            shape: Shape::ALL[(k + j) % n],
            speed: SPEEDS[k % SPEEDS.len()],
            seed: (k * 100 + j) as u64,
            ..GeneratorParams::default()
        })
        .collect();
    (name, strokes)
}

#[derive(Debug, Serialize)]
struct DemoSummary<'a> {
    proxy: &'a str,
    /// The browser page of the session (its token in the fragment), like the token only with
    /// `--keep-serving`.
    #[serde(skip_serializing_if = "Option::is_none")]
    page: Option<&'a str>,
    session: uuid::Uuid,
    #[serde(skip_serializing_if = "Option::is_none")]
    token: Option<&'a str>,
    database: &'a Path,
    database_is_temporary: bool,
    out_dir: &'a Path,
    totals: Totals,
    strokes: &'a [StrokeReport],
}

pub fn run(args: &DemoArgs) -> anyhow::Result<()> {
    init_tracing(args.live.verbose);
    anyhow::ensure!(
        args.people > 0 || args.keep_serving,
        "--people 0 draws nothing; add --keep-serving to only run the proxy"
    );
    anyhow::ensure!(args.people <= 256, "--people {} is more than the demo's 256", args.people);
    let (db, temporary) = match &args.db {
        Some(path) => {
            if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
                fs_err::create_dir_all(parent)?;
            }
            (path.clone(), None)
        }
        None => {
            let dir = tempfile::Builder::new()
                .prefix("penmesh-demo-")
                .tempdir()
                .context("cannot create a temporary folder for the database")?;
            (dir.path().join("penmesh.db"), Some(dir))
        }
    };
    fs_err::create_dir_all(&args.out)?;
    let out_dir = std::fs::canonicalize(&args.out).unwrap_or_else(|_| args.out.clone());
    let db = absolute(&db);

    runtime()?.block_on(async {
        let mut config = Config::defaults();
        config.host = args.host.clone();
        config.port = args.port;
        config.database_url = format!("sqlite://{}", db.display()).into();
        config.shutdown_grace_secs = 5;
        let app = Application::build(config).await.context("starting the proxy")?;
        let port = app.port();
        let base = format!("http://{}:{port}", args.host);
        let shutdown = app.shutdown_handle();
        let server = tokio::spawn(app.run_until_stopped());

        let session = create_session(&base).await?;
        let endpoint = Endpoint::new(&base, session.session, session.token.clone())?;
        let page = page_url(&args.host, port, &session);
        if args.live.json {
            eprintln!("watch and draw: {page}");
        } else {
            println!("watch and draw: {page}");
            if !args.keep_serving {
                println!("  (the proxy stops when the drawing ends; add --keep-serving to keep the page live)");
            }
        }
        let reports = if args.people > 0 {
            draw_together(args, &endpoint, &out_dir).await
        } else {
            Ok(Vec::new())
        };
        let reports = match reports {
            Ok(reports) => reports,
            Err(err) => {
                shutdown.cancel();
                let _ = server.await;
                return Err(err);
            }
        };

        let summary = DemoSummary {
            proxy: &base,
            page: args.keep_serving.then_some(page.as_str()),
            session: session.session,
            token: args.keep_serving.then_some(session.token.as_str()),
            database: &db,
            database_is_temporary: temporary.is_some(),
            out_dir: &out_dir,
            totals: Totals::of(&reports),
            strokes: &reports,
        };
        if args.live.json {
            println!("{}", serde_json::to_string(&summary)?);
        } else {
            if !reports.is_empty() {
                print!("{}", report::table(&reports));
                println!("GLB files: {} ({} files)", out_dir.display(), reports.len());
            }
            if temporary.is_some() {
                println!(
                    "database:  {} (temporary, removed on exit; pass --db PATH to keep it)",
                    db.display()
                );
            } else {
                println!("database:  {}", db.display());
            }
            if args.keep_serving {
                println!("proxy:     {base}");
                println!("session:   {}", session.session);
                println!("token:     {}", session.token);
                println!(
                    "join with: penmesh draw --server {base} --session {} --token {} --synth leaf",
                    session.session, session.token
                );
                println!("serving until Ctrl-C");
            }
        }
        use std::io::Write;
        let _ = std::io::stdout().flush();
        if !args.keep_serving {
            shutdown.cancel();
        }
        server.await.context("the proxy task failed")??;
        anyhow::Ok(())
    })?;
    drop(temporary);
    Ok(())
}

/// Every person draws on a task of their own; the reports come back person by person.
async fn draw_together(
    args: &DemoArgs,
    endpoint: &Endpoint,
    out_dir: &Path,
) -> anyhow::Result<Vec<StrokeReport>> {
    let pacing = if args.fast { Pacing::Fast } else { Pacing::Realtime };
    let bars = MultiProgress::new();
    let mut people = tokio::task::JoinSet::new();
    for k in 0..args.people {
        let (name, strokes) = plan(k);
        let source = ReplaySource::synth(&strokes, pacing)?;
        let mut options = draw_options(&args.live, &name)?;
        options.out_dir = Some(out_dir.to_path_buf());
        if !args.live.json {
            options.progress = Some(bars.add(progress_bar(source.total_samples(), &name)));
        }
        let endpoint = endpoint.clone();
        people.spawn(async move {
            let result = live::draw(&endpoint, Box::new(source), &options).await;
            if let Some(bar) = &options.progress {
                bar.finish_and_clear();
            }
            (k, result.with_context(|| format!("{name} could not finish drawing")))
        });
    }
    let mut by_person = Vec::new();
    while let Some(joined) = people.join_next().await {
        let (k, reports) = joined.context("a drawing task failed")?;
        by_person.push((k, reports?));
    }
    by_person.sort_by_key(|(k, _)| *k);
    Ok(by_person.into_iter().flat_map(|(_, reports)| reports).collect())
}

async fn create_session(base: &str) -> anyhow::Result<NewSession> {
    penmesh_client::api::create_session(&reqwest::Client::new(), base).await
}

/// The session's page. The token rides in the fragment, which the browser never sends.
fn page_url(host: &str, port: u16, session: &NewSession) -> String {
    let host = match host {
        "0.0.0.0" | "::" | "[::]" => "127.0.0.1",
        host => host,
    };
    format!("http://{host}:{port}/s/{}#token={}", session.session, session.token)
}

fn absolute(path: &Path) -> PathBuf {
    std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf())
}

/// `penmesh-lab serve-proxy` (hidden): the proxy, the same code as the `penmesh-proxy` binary,
/// so that `penmesh-lab load --spawn-proxy` needs nothing but this program.
#[derive(Debug, clap::Args)]
pub struct ServeProxyArgs {
    /// The proxy's own flags (see `penmesh-proxy --help`).
    #[arg(trailing_var_arg = true, allow_hyphen_values = true)]
    pub args: Vec<String>,
}

pub fn serve_proxy(args: &ServeProxyArgs) -> anyhow::Result<()> {
    let config = Config::load_from(
        std::iter::once("penmesh-proxy".to_string()).chain(args.args.iter().cloned()),
    )?;
    penmesh_proxy::init_tracing();
    penmesh_proxy::run(config)
}
