//! The OpenAPI document served at `/v1/openapi.json`.

use utoipa::openapi::security::{HttpAuthScheme, HttpBuilder, SecurityScheme};
use utoipa::{Modify, OpenApi};

use crate::{export, http, import, mesh_build, placement, removal, session_meshes, solid};

/// The proxy's HTTP API.
#[derive(Debug, OpenApi)]
#[openapi(
    info(title = "penmesh proxy", description = "Sessions, strokes, simplified trajectories and meshes. \
        The WebSocket ingest is GET /v1/sessions/{session}/ws (bearer token, or for browsers the `penmesh.token.TOKEN` \
        WebSocket subprotocol). Reads need the session's token; storing or building a stroke's mesh, and taking \
        a stroke back or bringing it back, or placing it (PUT /v1/strokes/{id}/placement), and importing a model (POST /v1/sessions/{session}/import), also need its drawer's participant key (the `key` of its WebSocket \
        `Hello`) in the `x-penmesh-key` header."),
    paths(
        http::create_session,
        http::list_strokes,
        export::export_print,
        import::import_scene,
        http::simplified,
        http::raw,
        http::put_mesh,
        http::get_mesh,
        session_meshes::session_meshes,
        mesh_build::build_mesh,
        removal::remove_stroke,
        removal::restore_stroke,
        placement::put_placement,
        placement::placements,
        placement::duplicate,
        solid::put_solid,
        solid::solids,
        http::healthz,
        http::readyz,
        http::metrics,
    ),
    components(schemas(
        http::NewSession,
        http::StrokeInfo,
        penmesh::protocol::Removal,
        http::StrokeList,
        http::StrokeSamples,
        http::MeshInfo,
        http::ErrorBody,
        penmesh::Placement,
        penmesh::protocol::PlacementChange,
        penmesh::protocol::PlacementHistory,
        penmesh::Solid,
        penmesh::SolidKind,
        penmesh::protocol::SolidChange,
        penmesh::protocol::SolidHistory,
        penmesh::protocol::DuplicateRequest,
        penmesh::protocol::Duplicated,
        penmesh::protocol::Imported,
        penmesh::protocol::ImportedStroke
    )),
    modifiers(&BearerAuth)
)]
pub struct ApiDoc;

struct BearerAuth;

impl Modify for BearerAuth {
    fn modify(&self, openapi: &mut utoipa::openapi::OpenApi) {
        let components = openapi.components.get_or_insert_with(Default::default);
        components.add_security_scheme(
            "bearer",
            SecurityScheme::Http(HttpBuilder::new().scheme(HttpAuthScheme::Bearer).build()),
        );
    }
}
