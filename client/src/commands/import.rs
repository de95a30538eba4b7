//! `penmesh import`: a GLB that penmesh exported, brought back into a session through the
//! proxy (`POST /v1/sessions/{id}/import`): each stroke re-created with the same samples,
//! brush and placement, drawn by this participant (`--key`, a new one by default), the
//! original author kept. All or nothing: the proxy stores every stroke or none.

use std::io::Write as _;
use std::path::PathBuf;
use std::time::Duration;

use anyhow::Context;
use clap::Args;
use penmesh::protocol::{Imported, KEY_HEADER};

#[derive(Debug, Clone, Args)]
pub struct ImportArgs {
    #[command(flatten)]
    pub connection: crate::commands::args::ConnectionArgs,
    /// Your participant key (the strokes' drawer); a new one when absent.
    #[arg(long, env = "PENMESH_KEY", hide_env_values = true)]
    pub key: Option<String>,
    /// Your name, shown as the strokes' drawer.
    #[arg(long, default_value = "penmesh import")]
    pub name: String,
    /// The GLB exported by penmesh.
    pub file: PathBuf,
}

pub fn run(args: &ImportArgs) -> anyhow::Result<()> {
    let endpoint = args.connection.endpoint()?;
    let bytes = fs_err::read(&args.file)?;
    let key = args.key.clone().unwrap_or_else(crate::wire::new_participant_key);
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .context("starting the runtime")?;
    let imported = runtime.block_on(async {
        let url = endpoint.url(&crate::api::session_import(args.connection.session));
        let http = reqwest::Client::builder()
            .timeout(Duration::from_secs(300))
            .build()
            .context("starting the HTTP client")?;
        let response = http
            .post(&url)
            .query(&[("name", args.name.as_str())])
            .bearer_auth(&endpoint.token)
            .header(KEY_HEADER, &key)
            .header("content-type", "model/gltf-binary")
            .body(bytes)
            .send()
            .await
            .with_context(|| format!("cannot reach the proxy: POST {url}"))?;
        let status = response.status();
        let body = response.text().await.context("reading the proxy's answer")?;
        if !status.is_success() {
            let message = serde_json::from_str::<penmesh::protocol::ErrorBody>(&body)
                .map(|e| e.message)
                .unwrap_or(body);
            anyhow::bail!("the proxy refused the import ({status}): {message}");
        }
        serde_json::from_str::<Imported>(&body).context("the proxy's answer is not an import")
    })?;
    // Written, not printed: a closed pipe (`| head`) is an error to report, not a panic.
    let mut out = std::io::stdout().lock();
    writeln!(out, "imported {} strokes from {}", imported.strokes.len(), args.file.display())?;
    for stroke in &imported.strokes {
        writeln!(out, "{} (was {})", stroke.stroke, stroke.source)?;
    }
    Ok(())
}
