//! `penmesh export`: a session's model taken out through the proxy's one export path
//! (`GET /v1/sessions/{id}/export`): the scene as GLB, or the print as STL or 3MF. The proxy
//! makes the file (a bounded job); the CLI shows a spinner with the time while the proxy works,
//! then a bar of the bytes received, and writes the file only once it is whole.

use std::path::PathBuf;
use std::time::Duration;

use anyhow::Context;
use clap::{Args, ValueEnum};
use indicatif::{ProgressBar, ProgressStyle};

use crate::endpoint::Endpoint;

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
    let total = response.content_length();
    bar.set_style(
        ProgressStyle::with_template("[{bar:30}] {bytes}/{total_bytes} {elapsed}")
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    if let Some(total) = total {
        bar.set_length(total);
    }
    let mut response = response;
    let mut bytes = Vec::with_capacity(total.unwrap_or(0) as usize);
    while let Some(chunk) = response.chunk().await.context("the export was cut off")? {
        bytes.extend_from_slice(&chunk);
        bar.set_position(bytes.len() as u64);
    }
    bar.finish_and_clear();
    if let Some(total) = total {
        anyhow::ensure!(
            bytes.len() as u64 == total,
            "the export was cut off: {} of {total} bytes",
            bytes.len()
        );
    }
    Ok(bytes)
}
