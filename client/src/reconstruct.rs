//! After a stroke is done: fetch its simplified form over HTTP, build the LRPDP solid mesh,
//! write the GLB, upload it, and measure the whole trip.

use std::path::PathBuf;
use std::time::Duration;

use anyhow::Context;
use penmesh::protocol::{ErrorBody, MeshInfo, StrokeSamples};
use penmesh::{GlbMeta, GlbOptions, OutlineOptions, Sample};
use serde::{Deserialize, Serialize};
use tokio::time::Instant;
use uuid::Uuid;

use crate::backoff::Backoff;
use crate::draw_options::DrawOptions;
use crate::endpoint::Endpoint;

/// A stroke the proxy has stored, with what the client drew.
#[derive(Debug, Clone)]
pub struct FinishedStroke {
    pub id: Uuid,
    /// Drawing order of this person's strokes.
    pub index: usize,
    pub device: String,
    /// Every drawn sample, snapped to the codec's grid.
    pub drawn: Vec<Sample>,
    /// For each resampled (streamed) sample, its index in `drawn`.
    pub resampled_from: Vec<usize>,
    pub pen_up: Instant,
}

/// One line of the summary table.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct StrokeReport {
    pub stroke: Uuid,
    pub name: String,
    pub device: String,
    pub index: usize,
    /// Samples the pen produced.
    pub n_drawn: usize,
    /// Samples kept by stage 1 and streamed.
    pub n_resampled: usize,
    /// Samples the proxy's stage 2 retained.
    pub n_retained: usize,
    /// Compression ratio against the drawn samples, %.
    pub cr: f64,
    /// Largest distance of a drawn sample to its retained segment, px.
    pub e_max: f64,
    pub vertices: u64,
    pub triangles: u64,
    pub glb_bytes: u64,
    /// From pen-up to the mesh being stored, ms.
    pub latency_ms: f64,
    /// The simplified stroke from the proxy is exactly the drawn samples at its indices.
    pub exact: bool,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub glb_path: Option<PathBuf>,
}

pub async fn reconstruct(
    http: &reqwest::Client,
    endpoint: &Endpoint,
    options: &DrawOptions,
    stroke: FinishedStroke,
) -> anyhow::Result<StrokeReport> {
    let id = stroke.id;
    let since_pen_up = |step: &str| {
        tracing::debug!(stroke = %id, ms = stroke.pen_up.elapsed().as_secs_f64() * 1e3, "{step}");
    };
    since_pen_up("stroke done");
    let url = endpoint.url(&crate::api::stroke_simplified(id));
    let simplified: StrokeSamples = with_retries(options.retry_for, || async {
        let response = http.get(&url).bearer_auth(&endpoint.token).send().await?;
        Ok(response)
    })
    .await
    .with_context(|| format!("fetching the simplified stroke {id}"))?
    .json()
    .await
    .with_context(|| format!("reading the simplified stroke {id}"))?;

    let indices = simplified
        .indices
        .as_deref()
        .with_context(|| format!("stroke {id}: the simplified stroke came without its indices"))?;
    anyhow::ensure!(
        indices.len() == simplified.samples.len(),
        "stroke {id}: the proxy sent {} indices for {} samples",
        indices.len(),
        simplified.samples.len()
    );
    let mut kept = Vec::with_capacity(indices.len());
    for &i in indices {
        let drawn_idx = *stroke.resampled_from.get(i as usize).with_context(|| {
            format!(
                "stroke {id}: retained index {i} is past the {} streamed samples",
                stroke.resampled_from.len()
            )
        })?;
        kept.push(drawn_idx);
    }
    since_pen_up("simplified fetched");
    let exact = kept.iter().zip(&simplified.samples).all(|(&i, s)| stroke.drawn[i] == *s);
    if !exact {
        tracing::warn!(stroke = %id, "the simplified stroke differs from what was drawn");
    }
    let metrics = penmesh::simplification_metrics(&stroke.drawn, &kept)
        .with_context(|| format!("stroke {id}: measuring the simplification"))?;

    // The smooth centreline (the default), checked against what was drawn when the proxy's
    // stroke is exactly the drawn samples it kept.
    let outline_options = OutlineOptions::default();
    let meta = GlbMeta { stroke: id, author: options.name.clone(), brush: options.brush };
    let glb_options = GlbOptions::default().encoding(options.glb);
    let solid = options.solid;
    let glb = if exact {
        penmesh::mesh_drawn_solid(
            &stroke.drawn,
            &kept,
            &meta,
            &solid,
            &outline_options,
            &glb_options,
        )
        .with_context(|| format!("stroke {id}: meshing it as {solid}"))?
        .glb
    } else {
        penmesh::mesh_retained_solid(
            &simplified.samples,
            &meta,
            &solid,
            &outline_options,
            &glb_options,
        )
        .with_context(|| format!("stroke {id}: meshing it as {solid}"))?
        .glb
    };
    if !solid.is_rod() {
        // The proxy checks it too, and builds its own mesh of it; the upload below replaces
        // that with this one, built from what was drawn.
        let url = endpoint.url(&crate::api::stroke_solid(id));
        with_retries(options.retry_for, || async {
            http.put(&url)
                .bearer_auth(&endpoint.token)
                .header(penmesh::protocol::KEY_HEADER, options.key.as_str())
                .json(&solid)
                .send()
                .await
        })
        .await
        .with_context(|| format!("setting stroke {id}'s solid ({solid})"))?;
    }

    since_pen_up("mesh built");
    let glb_path = match &options.out_dir {
        Some(dir) => {
            let path = dir.join(glb_file_name(&options.name, stroke.index, &stroke.device, id));
            let bytes = glb.clone();
            let written = path.clone();
            tokio::task::spawn_blocking(move || crate::io::write_file(&written, bytes)).await??;
            Some(path)
        }
        None => None,
    };

    let url = endpoint.url(&crate::api::stroke_mesh(id));
    let stored: MeshInfo = with_retries(options.retry_for, || async {
        let response = http
            .put(&url)
            .bearer_auth(&endpoint.token)
            .header("content-type", "model/gltf-binary")
            .header(penmesh::protocol::KEY_HEADER, options.key.as_str())
            .body(glb.clone())
            .send()
            .await?;
        Ok(response)
    })
    .await
    .with_context(|| format!("uploading the mesh of stroke {id}"))?
    .json()
    .await
    .with_context(|| format!("reading the answer to the mesh upload of stroke {id}"))?;
    let latency_ms = stroke.pen_up.elapsed().as_secs_f64() * 1e3;
    since_pen_up("mesh stored");
    anyhow::ensure!(
        stored.bytes == glb.len() as u64,
        "stroke {id}: the proxy stored {} bytes of a {}-byte GLB",
        stored.bytes,
        glb.len()
    );

    Ok(StrokeReport {
        stroke: id,
        name: options.name.clone(),
        device: stroke.device,
        index: stroke.index,
        n_drawn: stroke.drawn.len(),
        n_resampled: stroke.resampled_from.len(),
        n_retained: kept.len(),
        cr: metrics.cr,
        e_max: metrics.e_max,
        vertices: stored.vertices,
        triangles: stored.triangles,
        glb_bytes: stored.bytes,
        latency_ms,
        exact,
        glb_path,
    })
}

/// `NAME-NN-SHAPE-ID8.glb`, with only file-name-safe characters.
fn glb_file_name(name: &str, index: usize, device: &str, id: Uuid) -> String {
    let clean = |s: &str| -> String {
        s.chars()
            .map(|c| if c.is_ascii_alphanumeric() || c == '-' { c } else { '_' })
            .take(40)
            .collect()
    };
    let kind = device.rsplit(':').next().unwrap_or(device);
    let id = id.simple().to_string();
    format!("{}-{index:02}-{}-{}.glb", clean(name), clean(kind), &id[..8])
}

/// Sends a request until it succeeds, retrying connection failures and 5xx answers with
/// backoff for up to `budget`. A 4xx answer fails at once with the proxy's message.
async fn with_retries<F, Fut>(budget: Duration, mut request: F) -> anyhow::Result<reqwest::Response>
where
    F: FnMut() -> Fut,
    Fut: Future<Output = Result<reqwest::Response, reqwest::Error>>,
{
    let started = Instant::now();
    let mut backoff = Backoff::default();
    loop {
        let err = match request().await {
            Ok(response) if response.status().is_success() => return Ok(response),
            Ok(response) if response.status().is_client_error() => {
                let status = response.status();
                let body = response.text().await.unwrap_or_default();
                let message =
                    serde_json::from_str::<ErrorBody>(&body).map(|e| e.message).unwrap_or(body);
                anyhow::bail!("HTTP {status}: {message}");
            }
            Ok(response) => anyhow::anyhow!("HTTP {}", response.status()),
            Err(err) => anyhow::Error::new(err),
        };
        let delay = backoff.next_delay();
        if started.elapsed() + delay > budget {
            return Err(err);
        }
        tracing::info!(error = %format!("{err:#}"), "request failed; retrying");
        tokio::time::sleep(delay).await;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn glb_names_are_safe_and_readable() {
        let id = Uuid::parse_str("0123456789abcdef0123456789abcdef").unwrap();
        assert_eq!(
            glb_file_name("ada l/x", 3, "synth:figure8", id),
            "ada_l_x-03-figure8-01234567.glb"
        );
    }
}
