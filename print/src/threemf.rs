//! 3MF: a zip of the package's content types, its relationship to the model part, and the model
//! (`3D/3dmodel.model`, 3MF core 2015/02) with its unit set to millimetres: one object, one
//! mesh, one build item.

use std::fmt::Write as _;
use std::io::{Cursor, Write as _};

use zip::write::SimpleFileOptions;
use zip::{CompressionMethod, ZipWriter};

use crate::solid::PrintMesh;

const CONTENT_TYPES: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<Types xmlns="http://schemas.openxmlformats.org/package/2006/content-types"><Default Extension="rels" ContentType="application/vnd.openxmlformats-package.relationships+xml"/><Default Extension="model" ContentType="application/vnd.ms-package.3dmanufacturing-3dmodel+xml"/></Types>
"#;

const RELS: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<Relationships xmlns="http://schemas.openxmlformats.org/package/2006/relationships"><Relationship Target="/3D/3dmodel.model" Id="rel0" Type="http://schemas.microsoft.com/3dmanufacturing/2013/01/3dmodel"/></Relationships>
"#;

/// The path of the model part inside the package.
pub const MODEL_PATH: &str = "3D/3dmodel.model";

/// The model part's XML: the mesh in millimetres.
pub fn model_xml(mesh: &PrintMesh) -> String {
    let mut xml = String::with_capacity(64 * mesh.positions.len() + 48 * mesh.indices.len() / 3);
    xml.push_str(concat!(
        r#"<?xml version="1.0" encoding="UTF-8"?>"#,
        "\n",
        r#"<model unit="millimeter" xml:lang="en-US" xmlns="http://schemas.microsoft.com/3dmanufacturing/core/2015/02">"#,
        r#"<metadata name="Application">penmesh</metadata>"#,
        r#"<resources><object id="1" type="model" name="penmesh print"><mesh><vertices>"#,
    ));
    for [x, y, z] in &mesh.positions {
        // Writing to a String cannot fail.
        let _ = write!(xml, r#"<vertex x="{x}" y="{y}" z="{z}"/>"#);
    }
    xml.push_str("</vertices><triangles>");
    for [a, b, c] in mesh.triangles() {
        let _ = write!(xml, r#"<triangle v1="{a}" v2="{b}" v3="{c}"/>"#);
    }
    xml.push_str(
        r#"</triangles></mesh></object></resources><build><item objectid="1"/></build></model>"#,
    );
    xml.push('\n');
    xml
}

/// The mesh as a 3MF package.
pub fn write_3mf(mesh: &PrintMesh) -> std::io::Result<Vec<u8>> {
    let mut zip = ZipWriter::new(Cursor::new(Vec::new()));
    let options = SimpleFileOptions::default().compression_method(CompressionMethod::Deflated);
    for (path, text) in [
        ("[Content_Types].xml", CONTENT_TYPES.to_owned()),
        ("_rels/.rels", RELS.to_owned()),
        (MODEL_PATH, model_xml(mesh)),
    ] {
        zip.start_file(path, options)?;
        zip.write_all(text.as_bytes())?;
    }
    Ok(zip.finish()?.into_inner())
}
