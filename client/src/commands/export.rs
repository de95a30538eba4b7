//! `penmesh export`: a session's model taken out through the proxy's one export path
//! (`GET /v1/sessions/{id}/export`): the scene as GLB, or the print as STL or 3MF. The proxy
//! makes the file (a bounded job) and, asked with `Accept: application/x-ndjson`, tells its
//! progress line by line before the file; the CLI shows a bar of each stage's steps (reading,
//! solids, union) and writes the file only once it is whole. A proxy that answers the file
//! alone gets a bar of the bytes received.

use std::path::PathBuf;
use std::time::Duration;

use anyhow::Context;
use base64::Engine as _;
use clap::{Args, ValueEnum};
use indicatif::{ProgressBar, ProgressStyle};

use crate::endpoint::Endpoint;

/// The media type of the export's progress lines (`Accept`).
const PROGRESS_TYPE: &str = "application/x-ndjson";

/// What to export.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ExportFormat {
    /// The scene: a node per stroke, its placement, mesh and pen data (glTF, metres).
    Glb,
    /// The print: one closed manifold in millimetres (binary STL).
    Stl,
    /// The print as a 3MF package (unit millimetre).
    #[value(name = "3mf")]
    ThreeMf,
}

impl ExportFormat {
    fn query(self) -> &'static str {
        match self {
            ExportFormat::Glb => "glb",
            ExportFormat::Stl => "stl",
            ExportFormat::ThreeMf => "3mf",
        }
    }
}

#[derive(Debug, Clone, Args)]
pub struct ExportArgs {
    #[command(flatten)]
    pub connection: crate::commands::args::ConnectionArgs,
    /// glb (the scene), stl or 3mf (the print).
    #[arg(long, value_enum)]
    pub format: ExportFormat,
    /// Where to write the file.
    #[arg(long, value_name = "FILE")]
    pub out: PathBuf,
    /// Only these strokes (ids, comma-separated); every done stroke by default.
    #[arg(long, value_delimiter = ',', value_name = "ID,…")]
    pub strokes: Vec<uuid::Uuid>,
    /// The model's longest side, in millimetres.
    #[arg(long, default_value_t = 100.0)]
    pub size_mm: f64,
    /// Every part of a print at least this thick, in millimetres.
    #[arg(long, default_value_t = 0.8)]
    pub min_thickness_mm: f64,
    /// How long to wait for the proxy to make the file, in seconds.
    #[arg(long, default_value_t = 300)]
    pub timeout_secs: u64,
}

pub fn run(args: &ExportArgs) -> anyhow::Result<()> {
    let endpoint = args.connection.endpoint()?;
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .context("starting the runtime")?;
    let bytes = runtime.block_on(fetch(args, &endpoint))?;
    crate::io::write_file(&args.out, &bytes)?;
    eprintln!("wrote {} ({} bytes)", args.out.display(), bytes.len());
    Ok(())
}

/// The export's URL.
pub fn export_url(args: &ExportArgs, endpoint: &Endpoint) -> String {
    let mut url = format!(
        "{}?format={}&size_mm={}&min_thickness_mm={}",
        endpoint.url(&crate::api::session_export(args.connection.session)),
        args.format.query(),
        args.size_mm,
        args.min_thickness_mm
    );
    if !args.strokes.is_empty() {
        let ids: Vec<String> = args.strokes.iter().map(uuid::Uuid::to_string).collect();
        url.push_str(&format!("&strokes={}", ids.join(",")));
    }
    url
}

/// The proxy's answer to an export asked with its progress (`Accept: application/x-ndjson`,
/// docs/protocol.md): one of these per line.
#[derive(Debug, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
enum Line {
    Progress { stage: String, done: u64, total: u64 },
    File { bytes: usize, base64: String },
    Error { status: u16, code: String, message: String },
}

async fn fetch(args: &ExportArgs, endpoint: &Endpoint) -> anyhow::Result<Vec<u8>> {
    let url = export_url(args, endpoint);
    let http = reqwest::Client::builder()
        .timeout(Duration::from_secs(args.timeout_secs))
        .build()
        .context("starting the HTTP client")?;
    let bar = ProgressBar::new_spinner().with_style(
        ProgressStyle::with_template("{spinner} the proxy is making the {msg} {elapsed}")
            .unwrap_or_else(|_| ProgressStyle::default_spinner()),
    );
    bar.set_message(args.format.query());
    bar.enable_steady_tick(Duration::from_millis(100));
    let response = http
        .get(&url)
        .bearer_auth(&endpoint.token)
        .header(reqwest::header::ACCEPT, PROGRESS_TYPE)
        .send()
        .await
        .with_context(|| format!("cannot reach the proxy: GET {url}"))?;
    if !response.status().is_success() {
        bar.finish_and_clear();
        let status = response.status();
        let body = response.text().await.unwrap_or_default();
        let message = serde_json::from_str::<penmesh::protocol::ErrorBody>(&body)
            .map(|e| e.message)
            .unwrap_or(body);
        anyhow::bail!("the proxy refused the export ({status}): {message}");
    }
    let streamed = response
        .headers()
        .get(reqwest::header::CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .is_some_and(|v| v.starts_with(PROGRESS_TYPE));
    let bytes = if streamed {
        read_progress(response, &bar, args.format.query()).await
    } else {
        read_file(response, &bar).await
    };
    bar.finish_and_clear();
    bytes
}

/// The export's file from its progress lines, the bar showing each stage's steps.
async fn read_progress(
    mut response: reqwest::Response,
    bar: &ProgressBar,
    format: &str,
) -> anyhow::Result<Vec<u8>> {
    bar.set_style(
        ProgressStyle::with_template("{msg:>16} [{bar:30}] {pos}/{len} {elapsed}")
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    let mut pending: Vec<u8> = Vec::new();
    loop {
        while let Some(end) = pending.iter().position(|&b| b == b'\n') {
            let line: Vec<u8> = pending.drain(..=end).collect();
            let line: Line = serde_json::from_slice(&line).with_context(|| {
                format!(
                    "the proxy sent a line that is not progress: {}",
                    String::from_utf8_lossy(&line)
                )
            })?;
            match line {
                Line::Progress { stage, done, total } => {
                    bar.set_message(format!("{format}: {stage}"));
                    bar.set_length(total);
                    bar.set_position(done);
                }
                Line::File { bytes, base64 } => {
                    let file = base64::engine::general_purpose::STANDARD
                        .decode(base64.as_bytes())
                        .context("the proxy sent a file that is not base64")?;
                    anyhow::ensure!(
                        file.len() == bytes,
                        "the export was cut off: {} of {bytes} bytes",
                        file.len()
                    );
                    return Ok(file);
                }
                Line::Error { status, code, message } => {
                    anyhow::bail!("the export failed ({status} {code}): {message}");
                }
            }
        }
        let chunk = response.chunk().await.context("the export was cut off")?;
        let Some(chunk) = chunk else {
            anyhow::bail!("the export was cut off before its file came");
        };
        pending.extend_from_slice(&chunk);
    }
}

/// The export's file as the body (a proxy that does not send progress), a bar of its bytes.
async fn read_file(mut response: reqwest::Response, bar: &ProgressBar) -> anyhow::Result<Vec<u8>> {
    let total = response.content_length();
    bar.set_style(
        ProgressStyle::with_template("[{bar:30}] {bytes}/{total_bytes} {elapsed}")
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    if let Some(total) = total {
        bar.set_length(total);
    }
    let mut bytes = Vec::with_capacity(total.unwrap_or(0) as usize);
    while let Some(chunk) = response.chunk().await.context("the export was cut off")? {
        bytes.extend_from_slice(&chunk);
        bar.set_position(bytes.len() as u64);
    }
    if let Some(total) = total {
        anyhow::ensure!(
            bytes.len() as u64 == total,
            "the export was cut off: {} of {total} bytes",
            bytes.len()
        );
    }
    Ok(bytes)
}
