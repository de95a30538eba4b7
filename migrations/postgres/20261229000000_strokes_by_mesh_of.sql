-- The strokes that show another's mesh row (duplicates, strokes.mesh_of), found by that row's
-- stroke: every mesh stored looks for the duplicates that share the row it replaces
-- (proxy/src/store/writer/sharing.rs). Most strokes share none, so only those that do are in it.
CREATE INDEX strokes_by_mesh_of ON strokes (mesh_of) WHERE mesh_of IS NOT NULL;
