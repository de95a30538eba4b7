//! Export, import, export gives the same file, byte for byte, its node order included
//! (issue 52): a session imported from a file lists its strokes in the file's order, so its
//! export is the file it was imported from, but for what names where the strokes now are
//! (their new ids, the importer, the time of the import).

use penmesh::protocol::KEY_HEADER;
use penmesh::{Sample, read_scene};
use penmesh_e2e::{TestProxy, TestSession, draw_stroke, spawn_proxy, stroke_samples};
use serde_json::json;
use uuid::Uuid;

async fn export_glb(proxy: &TestProxy, session: &TestSession) -> Vec<u8> {
    let path = format!("/v1/sessions/{}/export?format=glb", session.session);
    let response = proxy.get(&path, session).send().await.unwrap();
    assert_eq!(response.status(), 200);
    response.bytes().await.unwrap().to_vec()
}

async fn import(proxy: &TestProxy, session: &TestSession, glb: Vec<u8>) {
    let response = proxy
        .http
        .post(proxy.url(&format!("/v1/sessions/{}/import?name=Imogen", session.session)))
        .bearer_auth(&session.token)
        .header(KEY_HEADER, &session.key)
        .header("content-type", "model/gltf-binary")
        .body(glb)
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), 201, "{}", response.text().await.unwrap());
}

/// Where each stroke of a file first came from, in node order.
fn origins(glb: &[u8]) -> Vec<Uuid> {
    let strokes = read_scene(glb).unwrap();
    strokes
        .iter()
        .map(|s| s.extras.imported_from.as_ref().map_or(s.extras.stroke, |f| f.stroke))
        .collect()
}

/// `from` with every text naming the strokes' session replaced by `to`'s: the ids (and the
/// last 8 hex digits that name a node), the drawer and the time each was begun.
fn as_if_from(file: &[u8], from: &[u8], to: &[u8]) -> Vec<u8> {
    let (a, b) = (read_scene(from).unwrap(), read_scene(to).unwrap());
    assert_eq!(a.len(), b.len());
    let mut text = file.to_vec();
    let mut swap = |old: String, new: String| {
        assert_eq!(old.len(), new.len());
        let (old, new) = (old.as_bytes(), new.as_bytes());
        let mut i = 0;
        while i + old.len() <= text.len() {
            if &text[i..i + old.len()] == old {
                text[i..i + old.len()].copy_from_slice(new);
                i += old.len();
            } else {
                i += 1;
            }
        }
    };
    for (x, y) in a.iter().zip(&b) {
        let (xs, ys) = (x.extras.stroke.to_string(), y.extras.stroke.to_string());
        swap(format!("stroke {} by", &xs[28..]), format!("stroke {} by", &ys[28..]));
        swap(xs, ys);
        swap(x.extras.author.participant.to_string(), y.extras.author.participant.to_string());
        swap(
            format!("\"drawn_at\":{}", x.extras.drawn_at),
            format!("\"drawn_at\":{}", y.extras.drawn_at),
        );
    }
    text
}

#[tokio::test]
async fn export_import_export_gives_the_same_file_in_the_same_order() {
    let proxy = spawn_proxy().await;
    let first = proxy.create_session().await;
    let mut drawer = proxy.connect(&first).await;
    drawer.hello(vec![]).await;
    let mut drawn = Vec::new();
    for i in 0..8 {
        let samples: Vec<Sample> = stroke_samples(60 + 10 * i)
            .into_iter()
            .map(|s| {
                let moved = Sample::new(s.x, s.y + 30.0 * i as f64, s.t, s.p);
                penmesh::protocol::quantize_sample(&moved)
            })
            .collect();
        let id = Uuid::new_v4();
        draw_stroke(&mut drawer, id, &samples, 50).await;
        assert_eq!(proxy.build_mesh(&first, id).send().await.unwrap().status(), 200);
        drawn.push(id);
    }
    let moved = json!({"matrix": [1, 0, 0, 0, 0, 0, 1, 0, 0, -1, 0, 0, 40.5, 0, 12.25, 1]});
    let response = proxy
        .http
        .put(proxy.url(&format!("/v1/strokes/{}/placement", drawn[3])))
        .bearer_auth(&first.token)
        .header(KEY_HEADER, &first.key)
        .json(&moved)
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), 204);
    let exported = export_glb(&proxy, &first).await;
    assert_eq!(origins(&exported), drawn, "the session's order is the drawing's");

    let second = proxy.create_session().await;
    import(&proxy, &second, exported).await;
    let once = export_glb(&proxy, &second).await;
    assert_eq!(origins(&once), drawn, "an import keeps the file's order");

    let third = proxy.create_session().await;
    import(&proxy, &third, once.clone()).await;
    let twice = export_glb(&proxy, &third).await;
    assert_eq!(origins(&twice), drawn);
    assert!(
        as_if_from(&twice, &twice, &once) == once,
        "the export of an import is not the file imported, but for the session's own names"
    );
}
