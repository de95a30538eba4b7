//! The bodies of the HTTP API (`docs/ARCHITECTURE.md`, `/v1/openapi.json`), beside the
//! WebSocket messages: the proxy answers with them and the clients read them, one definition.

use serde::{Deserialize, Serialize};
use utoipa::ToSchema;
use uuid::Uuid;

use super::StrokeStatus;
use crate::acuts::AcutsParams;
use crate::model::{Brush, Sample};
use crate::placement::Placement;
use crate::solid::Solid;

/// The JSON body of every error.
#[derive(Debug, Serialize, Deserialize, ToSchema)]
pub struct ErrorBody {
    /// Machine-readable: `unauthorized`, `forbidden`, `not_found`, `bad_request`, `conflict`,
    /// `too_large`, `too_many_requests`, `busy`, `shutting_down`, `internal`.
    pub error: String,
    pub message: String,
}

/// A new session.
#[derive(Debug, Serialize, Deserialize, ToSchema)]
pub struct NewSession {
    pub session: Uuid,
    /// The bearer token: shown once, stored only as a hash.
    pub token: String,
}

/// A stroke's metadata.
#[derive(Debug, Serialize, Deserialize, ToSchema)]
pub struct StrokeInfo {
    pub id: Uuid,
    pub session: Uuid,
    pub participant: Uuid,
    /// `open`, `done` or `interrupted`.
    pub status: StrokeStatus,
    pub n_points: u64,
    pub n_retained: u64,
    pub brush: Brush,
    /// The ACUTS stage 2 parameters the proxy simplified the stroke with.
    pub params: AcutsParams,
    pub device: Option<String>,
    pub has_mesh: bool,
    /// Milliseconds since the Unix epoch.
    pub created_at: i64,
    pub updated_at: i64,
    /// Set while the stroke is taken back (undo, the eraser): who took it back and when.
    /// Only listed with `?include=removed`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub removed: Option<Removal>,
    /// Where the stroke's plane stands in the session's 3D space: its current placement
    /// (the latest of `GET /v1/strokes/{id}/placements`); the identity by default.
    #[serde(default)]
    pub placement: Placement,
    /// The stroke this one is a duplicate of (`POST /v1/strokes/{id}/duplicate`), if any.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub duplicate_of: Option<Uuid>,
    /// What the stroke becomes (`PUT /v1/strokes/{id}/solid`): its kind and depth; a line
    /// with no depth (the pressure-width rod) by default.
    #[serde(default)]
    pub solid: Solid,
}

/// One placement a stroke had: which, who set it and when.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct PlacementChange {
    pub placement: Placement,
    /// The participant who set it: the stroke's drawer.
    pub by: Uuid,
    /// Milliseconds since the Unix epoch.
    pub at: i64,
    /// `begin` (the work plane the stroke was drawn on, the identity when none was given),
    /// `set` (moved, turned, scaled, mirrored, or an undo) or `duplicate` (the placement a
    /// duplicate was made with).
    pub cause: String,
}

/// Every placement a stroke had, oldest first: the last is its current one. Nothing is
/// overwritten, so undo restores the one before exactly.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct PlacementHistory {
    pub stroke: Uuid,
    pub placements: Vec<PlacementChange>,
    /// Where the next page begins (its `from`), when the history goes on past this page.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub next: Option<u64>,
}

/// One solid a stroke had: which, who set it and when.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct SolidChange {
    pub solid: Solid,
    /// The participant who set it: the stroke's drawer.
    pub by: Uuid,
    /// Milliseconds since the Unix epoch.
    pub at: i64,
    /// `begin` (the default rod, or the solid its stroke_begin carried), `set` (changed, or an
    /// undo), `duplicate` or `import`.
    pub cause: String,
}

/// Every solid a stroke had, oldest first: the last is its current one. Nothing is
/// overwritten.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct SolidHistory {
    pub stroke: Uuid,
    pub solids: Vec<SolidChange>,
    /// Where the next page begins (its `from`), when the history goes on past this page.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub next: Option<u64>,
}

/// The body of `POST /v1/strokes/{id}/duplicate`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct DuplicateRequest {
    /// The id of the new stroke (UUID v4, chosen by the client, so that a retried request is
    /// recognised); a fresh one when absent.
    #[serde(default)]
    pub stroke: Option<Uuid>,
    /// The new stroke's placement.
    pub placement: Placement,
}

/// A duplicate made: the new stroke and its source.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct Duplicated {
    pub stroke: Uuid,
    pub source: Uuid,
}

/// One stroke re-created by `POST /v1/sessions/{id}/import`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct ImportedStroke {
    /// Its id in the session.
    pub stroke: Uuid,
    /// Its id in the file (`extras.penmesh.stroke`).
    pub source: Uuid,
}

/// What an import re-created, in the file's order.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct Imported {
    pub strokes: Vec<ImportedStroke>,
}

/// Who took a stroke back, and when.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
pub struct Removal {
    /// The participant who took it back (its drawer).
    pub by: Uuid,
    /// Milliseconds since the Unix epoch.
    pub at: i64,
}

/// The strokes of a session, oldest first.
#[derive(Debug, Serialize, Deserialize, ToSchema)]
pub struct StrokeList {
    pub strokes: Vec<StrokeInfo>,
}

/// Samples of a stroke with its metadata.
#[derive(Debug, Serialize, Deserialize, ToSchema)]
pub struct StrokeSamples {
    #[serde(flatten)]
    pub stroke: StrokeInfo,
    /// For the simplified stroke: the index of each sample in the raw stroke.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub indices: Option<Vec<u64>>,
    /// `[x, y, t, p]` each.
    #[schema(value_type = Vec<[f64; 4]>)]
    pub samples: Vec<Sample>,
}

/// What a stored mesh holds.
#[derive(Debug, Serialize, Deserialize, ToSchema)]
pub struct MeshInfo {
    pub stroke: Uuid,
    pub bytes: u64,
    pub vertices: u64,
    pub triangles: u64,
    /// Who stored it: the drawer's participant id for an upload, `penmesh-proxy` for a mesh
    /// the proxy built (at the drawer's request).
    pub uploader: Option<String>,
}
