//! What one request of the model routes may cost (issue 49, `docs/reliability.md`): a print
//! nobody waits for stops and holds its permit until it has; a stranger's placement or
//! duplicate is refused before its body is read; a placement history is read a bounded page at
//! a time; duplicates count toward the session's sample quota and take a permit; a scene is
//! bounded by its samples; of two duplicates naming one new id exactly one is made, whole; and
//! a missing `x-penmesh-key` is 403 on every route that needs one (issue 52, item 6).

use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use penmesh::protocol::KEY_HEADER;
use penmesh_e2e::{
    TestProxy, TestSession, count_rows, draw_stroke, spawn_proxy, spawn_proxy_with, stroke_samples,
};
use serde_json::{Value, json};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use uuid::Uuid;

/// `samples` moved by `(dx, dy)`, on the codec's grid.
fn moved(samples: &[penmesh::Sample], dx: f64, dy: f64) -> Vec<penmesh::Sample> {
    samples
        .iter()
        .map(|s| {
            penmesh::protocol::quantize_sample(&penmesh::Sample::new(s.x + dx, s.y + dy, s.t, s.p))
        })
        .collect()
}

fn placement_json(dx: f64) -> Value {
    let mut m = *penmesh::Placement::IDENTITY.matrix();
    m[12] = dx;
    json!({ "matrix": m })
}

/// Sends a request head announcing a `length`-byte body and the first KiB of it, then waits up
/// to `wait` for the answer's status line: `None` when the proxy answers nothing (it waits for
/// the body).
async fn status_before_the_body(
    proxy: &TestProxy,
    method: &str,
    path: &str,
    headers: &[(&str, &str)],
    length: usize,
    wait: Duration,
) -> Option<u16> {
    let mut tcp = tokio::net::TcpStream::connect(("127.0.0.1", proxy.port)).await.unwrap();
    let mut head = format!(
        "{method} {path} HTTP/1.1\r\nhost: 127.0.0.1\r\ncontent-type: application/json\r\n\
         content-length: {length}\r\n"
    );
    for (name, value) in headers {
        head.push_str(&format!("{name}: {value}\r\n"));
    }
    head.push_str("\r\n");
    tcp.write_all(head.as_bytes()).await.unwrap();
    tcp.write_all(&vec![b' '; 1024]).await.unwrap();
    let mut answer = Vec::new();
    let read = async {
        let mut buf = [0u8; 1024];
        while !answer.windows(2).any(|w| w == b"\r\n") {
            match tcp.read(&mut buf).await {
                Ok(0) | Err(_) => break,
                Ok(n) => answer.extend_from_slice(&buf[..n]),
            }
        }
    };
    tokio::time::timeout(wait, read).await.ok()?;
    let line = String::from_utf8_lossy(&answer).into_owned();
    line.split(' ').nth(1)?.parse().ok()
}

/// (1) A print nobody waits for stops its work within 2 s, and holds its permit until the work
/// has stopped: never more prints at work than `MAX_PRINTS`. A request answered 408 was told
/// to ask again, so its print goes on for one request timeout (the retry's window, item 7),
/// then stops when nobody did; a progress body dropped stops it at once.
#[tokio::test]
async fn a_print_nobody_waits_for_stops_and_holds_its_permit_until_it_has() {
    let proxy = spawn_proxy_with(|c| c.request_timeout_secs = 1).await;
    let session = proxy.create_session().await;
    // Enough solids that the print outlasts the 1 s timeout.
    proxy.slow_print_model(&session).await;
    let path = format!("/v1/sessions/{}/export?format=stl", session.session);
    let working = || proxy.state.exports_working.load(Ordering::Relaxed);

    // Asked plainly: the request times out (408) while the print is at work, and nobody asks
    // again.
    let response = proxy.get(&path, &session).send().await.unwrap();
    assert_eq!(response.status(), 408);
    let left = Instant::now();
    assert_eq!(working(), 1, "the print outlasts its request (else this test shows nothing)");
    let window = Duration::from_secs(1);
    while working() > 0 {
        // While it works, it holds the permit: another print is refused.
        if let Some(permit) = proxy.state.export_permit(false) {
            assert_eq!(working(), 0, "a print's permit was free while its work went on");
            drop(permit);
        }
        assert!(
            left.elapsed() < window + Duration::from_secs(2),
            "the print went on past its retry window"
        );
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
    assert!(proxy.state.export_permit(false).is_some(), "the permit is free once it stopped");

    // Asked with its progress, the body dropped after the first line: the same.
    let response = proxy
        .http
        .get(proxy.url(&path))
        .bearer_auth(&session.token)
        .header("accept", "application/x-ndjson")
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), 200);
    let mut body = response;
    body.chunk().await.unwrap().expect("a first progress line");
    let started = Instant::now();
    while working() == 0 {
        assert!(started.elapsed() < Duration::from_secs(5), "the print's work never started");
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
    drop(body);
    let left = Instant::now();
    while working() > 0 {
        if let Some(permit) = proxy.state.export_permit(false) {
            assert_eq!(working(), 0, "a print's permit was free while its work went on");
            drop(permit);
        }
        assert!(left.elapsed() < Duration::from_secs(2), "the print went on after its client left");
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
}

/// A refusal to see: who, the request's headers, and the status expected.
type Case<'a> = (&'a str, Vec<(&'a str, &'a str)>, u16);

/// (2) `PUT …/placement` and `POST …/duplicate` authorise before they read a body: a wrong
/// token, a missing key or another participant's key is answered at once, with the announced
/// 15 MiB never sent; the drawer's body is bounded to what a placement needs (413 past it).
#[tokio::test]
async fn a_placement_or_duplicate_is_refused_before_its_body_is_read() {
    let proxy = spawn_proxy().await;
    let session = proxy.create_session().await;
    let stroke = proxy.done_stroke(&session, 200).await;
    let stranger = session.stranger();
    let wrong = format!("Bearer {}", "f".repeat(64));
    let token = format!("Bearer {}", session.token);
    let huge = 15 << 20;
    let wait = Duration::from_secs(5);
    for (method, path) in [
        ("PUT", format!("/v1/strokes/{stroke}/placement")),
        ("POST", format!("/v1/strokes/{stroke}/duplicate")),
    ] {
        let cases: [Case; 2] = [
            ("a wrong token", vec![("authorization", &wrong), (KEY_HEADER, &session.key)], 401),
            ("no key", vec![("authorization", &token)], 403),
        ];
        for (who, headers, status) in cases {
            let answer = status_before_the_body(&proxy, method, &path, &headers, huge, wait).await;
            assert_eq!(answer, Some(status), "{method} {path} with {who}");
        }
        // The drawer (or, for a duplicate, anyone with a key): a body past 16 KiB is 413.
        let headers = [("authorization", token.as_str()), (KEY_HEADER, session.key.as_str())];
        let answer = status_before_the_body(&proxy, method, &path, &headers, huge, wait).await;
        assert_eq!(answer, Some(413), "{method} {path}: a 15 MiB body");
    }
    let headers = [("authorization", token.as_str()), (KEY_HEADER, stranger.key.as_str())];
    let path = format!("/v1/strokes/{stroke}/placement");
    let answer = status_before_the_body(&proxy, "PUT", &path, &headers, huge, wait).await;
    assert_eq!(answer, Some(403), "another participant's placement");
    // A body of the right size still works, sent in pieces or not.
    let response = proxy
        .http
        .put(proxy.url(&path))
        .bearer_auth(&session.token)
        .header(KEY_HEADER, &session.key)
        .body(serde_json::to_vec(&placement_json(5.0)).unwrap())
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), 204);
}

/// `GET …/placements?from&limit` as `who`: the page.
async fn page(proxy: &TestProxy, who: &TestSession, stroke: Uuid, query: &str) -> Value {
    proxy.get_json(&format!("/v1/strokes/{stroke}/placements{query}"), who).await
}

/// A stroke's history (`route`: `placements` or `solids`) followed page after page from
/// `?from=0&limit={limit}`: every entry, oldest first.
async fn follow_pages(
    proxy: &TestProxy,
    who: &TestSession,
    stroke: Uuid,
    route: &str,
    limit: usize,
) -> Vec<Value> {
    let mut all = Vec::new();
    let mut from = Some(0);
    while let Some(at) = from {
        let path = format!("/v1/strokes/{stroke}/{route}?from={at}&limit={limit}");
        let body = proxy.get_json(&path, who).await;
        let got = body[route].as_array().unwrap();
        assert!(!got.is_empty() && got.len() <= limit, "{path}");
        all.extend(got.iter().cloned());
        from = body["next"].as_u64();
    }
    all
}

/// (Issue 51) A solid history is read a page at a time as a placement history is: at most
/// `MAX_HISTORY_PAGE` a page whatever is asked, `next` where the next begins, the pages
/// together the whole history in order.
#[tokio::test]
async fn a_solid_history_is_read_a_bounded_page_at_a_time() {
    // A history of 1,004 changes made at once: the rate of solid changes off.
    let proxy = spawn_proxy_with(|c| c.solid_rate_per_second = 0).await;
    let session = proxy.create_session().await;
    let stroke = proxy.done_stroke(&session, 20).await;
    let max = penmesh_proxy::MAX_HISTORY_PAGE as usize;
    // More changes than a page holds (the rod of its begin is implied: one more entry); each
    // a wall as deep as its number.
    let changes = max + 4;
    for chunk in (0..changes).collect::<Vec<_>>().chunks(16) {
        let puts = chunk.iter().map(|&i| {
            proxy
                .http
                .put(proxy.url(&format!("/v1/strokes/{stroke}/solid")))
                .bearer_auth(&session.token)
                .header(KEY_HEADER, &session.key)
                .json(&json!({"kind": "line", "depth": i as f64 + 1.0}))
                .send()
        });
        for response in futures_util::future::join_all(puts).await {
            assert_eq!(response.unwrap().status(), 200);
        }
    }
    let page = |query: &str| {
        let path = format!("/v1/strokes/{stroke}/solids{query}");
        let (proxy, session) = (&proxy, &session);
        async move { proxy.get_json(&path, session).await }
    };
    for query in ["", "?limit=100000"] {
        let first = page(query).await;
        assert_eq!(first["solids"].as_array().unwrap().len(), max, "{query}");
        assert_eq!(first["next"], max, "{query}");
        assert_eq!(first["solids"][0]["cause"], "begin");
    }
    let all = follow_pages(&proxy, &session, stroke, "solids", 300).await;
    assert_eq!(all, follow_pages(&proxy, &session, stroke, "solids", max).await);
    assert_eq!(all.len(), changes + 1);
    assert_eq!(all[0]["solid"], json!({"kind": "line", "depth": null}));
    let mut depths: Vec<u64> = all[1..]
        .iter()
        .map(|entry| {
            assert_eq!(entry["cause"], "set");
            entry["solid"]["depth"].as_f64().unwrap() as u64
        })
        .collect();
    depths.sort_unstable();
    assert_eq!(depths, (1..=changes as u64).collect::<Vec<_>>());
    let last = page(&format!("?from={changes}")).await;
    assert_eq!(last["solids"].as_array().unwrap().len(), 1);
    assert!(last.get("next").is_none(), "{last}");
    let past = page(&format!("?from={}", changes + 10)).await;
    assert_eq!(past["solids"], json!([]), "past the end: an empty page, no next");
    assert!(past.get("next").is_none(), "{past}");
}

/// A page of a history that does not read (`from` or `limit` not a whole number, a limit of
/// 0) is a JSON 400 naming what is wrong, on both histories.
#[tokio::test]
async fn a_bad_page_of_a_stroke_history_is_a_json_400_naming_it() {
    let proxy = spawn_proxy().await;
    let session = proxy.create_session().await;
    let stroke = proxy.done_stroke(&session, 20).await;
    for route in ["placements", "solids"] {
        for (query, says) in [
            ("from=-1", "from"),
            ("from=first", "from"),
            ("limit=ten", "limit"),
            ("limit=1.5", "limit"),
            ("limit=0", "limit=0"),
        ] {
            let path = format!("/v1/strokes/{stroke}/{route}?{query}");
            let response = proxy.get(&path, &session).send().await.unwrap();
            assert_eq!(response.status(), 400, "{path}");
            let body: Value = response.json().await.expect("a JSON error body");
            assert_eq!(body["error"], "bad_request", "{path}: {body}");
            let message = body["message"].as_str().unwrap();
            assert!(message.contains(says), "{path}: {message}");
        }
    }
}

/// (3) A placement history is read a page at a time, at most `MAX_HISTORY_PAGE` a page
/// whatever is asked: the pages, followed by `next`, are the whole history in order.
#[tokio::test]
async fn a_placement_history_is_read_a_bounded_page_at_a_time() {
    let proxy = spawn_proxy().await;
    let session = proxy.create_session().await;
    let stroke = proxy.done_stroke(&session, 200).await;
    let max = penmesh_proxy::MAX_HISTORY_PAGE as usize;
    // More moves than a page holds (the begin is implied: one more entry).
    let moves = max + 4;
    for chunk in (0..moves).collect::<Vec<_>>().chunks(16) {
        let puts = chunk.iter().map(|&i| {
            proxy
                .http
                .put(proxy.url(&format!("/v1/strokes/{stroke}/placement")))
                .bearer_auth(&session.token)
                .header(KEY_HEADER, &session.key)
                .json(&placement_json(i as f64 + 1.0))
                .send()
        });
        for response in futures_util::future::join_all(puts).await {
            assert_eq!(response.unwrap().status(), 204);
        }
    }
    // The default page and one asking for more: at most MAX_HISTORY_PAGE, and where next.
    for query in ["", "?limit=100000"] {
        let first = page(&proxy, &session, stroke, query).await;
        assert_eq!(first["placements"].as_array().unwrap().len(), max, "{query}");
        assert_eq!(first["next"], max, "{query}");
        assert_eq!(first["placements"][0]["cause"], "begin");
    }
    // Pages followed to the end, small or whole: the same history, oldest first, each move
    // once (they were sent 16 at a time, so in any order).
    let (proxy, session) = (&proxy, &session);
    let all = follow_pages(proxy, session, stroke, "placements", 300).await;
    assert_eq!(all, follow_pages(proxy, session, stroke, "placements", max).await);
    assert_eq!(all.len(), moves + 1);
    assert_eq!(all[0]["cause"], "begin");
    let mut moved: Vec<u64> = all[1..]
        .iter()
        .map(|entry| {
            assert_eq!(entry["cause"], "set");
            entry["placement"]["matrix"][12].as_f64().unwrap() as u64
        })
        .collect();
    moved.sort_unstable();
    assert_eq!(moved, (1..=moves as u64).collect::<Vec<_>>());
    // The last page has no next; a limit of 0 is refused.
    let last = page(proxy, session, stroke, &format!("?from={moves}")).await;
    assert_eq!(last["placements"].as_array().unwrap().len(), 1);
    assert!(last.get("next").is_none(), "{last}");
    let response = proxy
        .get(&format!("/v1/strokes/{stroke}/placements?limit=0"), session)
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), 400);
}

/// (4) A duplicate copies its source's samples inside the database and counts them toward the
/// session's sample quota (413 `quota_exceeded` past it, nothing stored); at most
/// `MAX_DUPLICATES` are made at once on a replica (503 `busy` past it).
#[tokio::test]
async fn duplicates_count_toward_the_sample_quota_and_take_a_permit() {
    let proxy = spawn_proxy_with(|c| {
        c.max_session_samples = 2_500;
        // A duplicate waits half of it for a permit.
        c.request_timeout_secs = 2;
    })
    .await;
    let session = proxy.create_session().await;
    let source = proxy.done_stroke(&session, 1_000).await;
    let (status, body) =
        proxy.duplicate(&session, source, json!({"placement": placement_json(1.0)})).await;
    assert_eq!(status, 201, "{body}");
    let copy: Uuid = body["stroke"].as_str().unwrap().parse().unwrap();
    assert_eq!(proxy.raw_samples(&session, copy).await, stroke_samples(1_000));
    let simplified = |stroke: Uuid| {
        let path = format!("/v1/strokes/{stroke}/simplified");
        let (proxy, session) = (&proxy, &session);
        async move { proxy.get_json(&path, session).await }
    };
    let (a, b) = (simplified(source).await, simplified(copy).await);
    assert_eq!(a["samples"], b["samples"]);
    assert_eq!(a["indices"], b["indices"]);
    assert_eq!(b["status"], "done");
    assert_eq!(b["n_retained"], a["n_retained"]);
    assert_eq!(b["n_points"], 1_000);
    // 2,000 stored: another 1,000 would pass 2,500.
    let (status, body) =
        proxy.duplicate(&session, source, json!({"placement": placement_json(2.0)})).await;
    assert_eq!(status, 413, "{body}");
    assert_eq!(body["error"], "quota_exceeded");
    assert!(body["message"].as_str().unwrap().contains("2500 samples"), "{body}");
    let strokes = count_rows(&proxy.db, "SELECT COUNT(*) FROM strokes").await;
    assert_eq!(strokes, 2, "nothing stored past the quota");

    // Every duplicate permit taken: the next duplicate waits its turn (1 s here), then is
    // busy, and nothing is stored.
    let mut held = Vec::new();
    for _ in 0..penmesh_proxy::MAX_DUPLICATES {
        held.push(proxy.state.duplicate_permit(Duration::ZERO).await.unwrap());
    }
    let asked = Instant::now();
    let (status, body) =
        proxy.duplicate(&session, copy, json!({"placement": placement_json(3.0)})).await;
    assert_eq!((status, body["error"].as_str()), (503, Some("busy")), "{body}");
    assert!(asked.elapsed() >= Duration::from_millis(900), "it waited its turn first");
    // A permit freed while it waits: it is made.
    let freed = async {
        tokio::time::sleep(Duration::from_millis(300)).await;
        held.pop();
    };
    let body = json!({"placement": placement_json(4.0)});
    let ((status, _), ()) = tokio::join!(proxy.duplicate(&session, copy, body), freed);
    assert_eq!(status, 413, "made once its turn came (past the quota here)");
    drop(held);
    assert_eq!(count_rows(&proxy.db, "SELECT COUNT(*) FROM strokes").await, 2);
}

/// (5) A scene holds at most `MAX_SCENE_SAMPLES` simplified samples: past it the export is
/// 413 naming the bound before anything is read; fewer strokes chosen are exported.
#[tokio::test]
async fn a_scene_past_its_sample_bound_is_refused() {
    // A session of many copies, made at once: the rate of duplicated samples off.
    let proxy = spawn_proxy_with(|c| c.duplicate_samples_per_second = 0).await;
    let session = proxy.create_session().await;
    let source = proxy.done_stroke(&session, 20_000).await;
    let retained = proxy.stroke_info(&session, source).await["n_retained"].as_u64().unwrap();
    let copies = penmesh_proxy::MAX_SCENE_SAMPLES / retained;
    assert!(copies < 700, "{retained} retained: too many duplicates to make");
    let mut last = source;
    for i in 0..copies {
        let (status, body) =
            proxy.duplicate(&session, source, json!({"placement": placement_json(i as f64)})).await;
        assert_eq!(status, 201, "{body}");
        last = body["stroke"].as_str().unwrap().parse().unwrap();
    }
    let path = format!("/v1/sessions/{}/export?format=glb", session.session);
    let response = proxy.get(&path, &session).send().await.unwrap();
    assert_eq!(response.status(), 413);
    let body: Value = response.json().await.unwrap();
    let message = body["message"].as_str().unwrap();
    assert!(message.contains(&penmesh_proxy::MAX_SCENE_SAMPLES.to_string()), "{message}");
    let response =
        proxy.get(&format!("{path}&strokes={source},{last}"), &session).send().await.unwrap();
    assert_eq!(response.status(), 200);
}

/// (6) Two duplicates naming the same new id at once: one is made (201), the other 409, and
/// the stored stroke is wholly the winner's source's. The winner's request sent again is
/// answered as made, and stores nothing twice.
#[tokio::test]
async fn of_two_duplicates_naming_one_new_id_exactly_one_is_made_whole() {
    let proxy = spawn_proxy().await;
    let session = proxy.create_session().await;
    let mut ws = proxy.connect(&session).await;
    ws.hello(vec![]).await;
    let (a, b) = (Uuid::new_v4(), Uuid::new_v4());
    draw_stroke(&mut ws, a, &stroke_samples(3_000), 500).await;
    draw_stroke(&mut ws, b, &moved(&stroke_samples(6_000), 7.0, 300.0), 500).await;
    let other = session.stranger();
    for round in 0..10 {
        let id = Uuid::new_v4();
        let body = json!({"stroke": id, "placement": placement_json(round as f64)});
        let (first, second) = tokio::join!(
            proxy.duplicate(&session, a, body.clone()),
            proxy.duplicate(&other, b, body.clone()),
        );
        let mut statuses = [first.0, second.0];
        statuses.sort();
        assert_eq!(statuses, [201, 409], "round {round}: {first:?} {second:?}");
        let (winner, source) = if first.0 == 201 { (&session, a) } else { (&other, b) };
        let info = proxy.stroke_info(&session, id).await;
        assert_eq!(info["duplicate_of"], source.to_string(), "round {round}");
        assert_eq!(
            proxy.raw_samples(&session, id).await,
            proxy.raw_samples(&session, source).await,
            "round {round}: the stored samples are one source's"
        );
        let simplified = |stroke: Uuid| {
            let path = format!("/v1/strokes/{stroke}/simplified");
            let session = session.clone();
            let proxy = &proxy;
            async move { proxy.get_json(&path, &session).await["samples"].clone() }
        };
        assert_eq!(simplified(id).await, simplified(source).await, "round {round}");
        // The winner's request again: answered as made, nothing stored twice.
        let strokes = count_rows(&proxy.db, "SELECT COUNT(*) FROM strokes").await;
        let again = proxy.duplicate(winner, source, body.clone()).await;
        assert_eq!(again.0, 201, "round {round}: {again:?}");
        assert_eq!(again.1["stroke"], id.to_string());
        assert_eq!(count_rows(&proxy.db, "SELECT COUNT(*) FROM strokes").await, strokes);
    }
}

/// Issue 52, item 6: a missing `x-penmesh-key` is 403 `forbidden`, naming the header, on every
/// route that needs one; a malformed key is 400.
#[tokio::test]
async fn a_missing_key_is_403_on_every_route_that_needs_one() {
    let proxy = spawn_proxy().await;
    let session = proxy.create_session().await;
    let stroke = proxy.done_stroke(&session, 200).await;
    let placement = serde_json::to_vec(&placement_json(1.0)).unwrap();
    let duplicate = serde_json::to_vec(&json!({"placement": placement_json(1.0)})).unwrap();
    let routes: Vec<(reqwest::Method, String, Vec<u8>)> = vec![
        (reqwest::Method::PUT, format!("/v1/strokes/{stroke}/placement"), placement),
        (reqwest::Method::POST, format!("/v1/strokes/{stroke}/duplicate"), duplicate),
        (reqwest::Method::DELETE, format!("/v1/strokes/{stroke}"), Vec::new()),
        (reqwest::Method::POST, format!("/v1/strokes/{stroke}/restore"), Vec::new()),
        (reqwest::Method::PUT, format!("/v1/strokes/{stroke}/mesh"), Vec::new()),
        (reqwest::Method::POST, format!("/v1/strokes/{stroke}/mesh/build"), Vec::new()),
        (reqwest::Method::POST, format!("/v1/sessions/{}/import", session.session), Vec::new()),
    ];
    for (method, path, body) in routes {
        for (key, status, error) in [(None, 403, "forbidden"), (Some("short"), 400, "bad_request")]
        {
            let mut request =
                proxy.http.request(method.clone(), proxy.url(&path)).bearer_auth(&session.token);
            if let Some(key) = key {
                request = request.header(KEY_HEADER, key);
            }
            let response = request.body(body.clone()).send().await.unwrap();
            assert_eq!(response.status(), status, "{method} {path} with key {key:?}");
            let answer: Value = response.json().await.unwrap();
            assert_eq!(answer["error"], error, "{method} {path}: {answer}");
            assert!(answer["message"].as_str().unwrap().contains(KEY_HEADER), "{answer}");
        }
    }
}

/// `POST /v1/sessions/{session}/import` of `glb` as `who`, with `key` as `Idempotency-Key`.
async fn import(proxy: &TestProxy, who: &TestSession, glb: &[u8], key: Option<&str>) -> Value {
    let mut request = proxy
        .http
        .post(proxy.url(&format!("/v1/sessions/{}/import", who.session)))
        .bearer_auth(&who.token)
        .header(KEY_HEADER, &who.key)
        .header("content-type", "model/gltf-binary")
        .body(glb.to_vec());
    if let Some(key) = key {
        request = request.header("idempotency-key", key);
    }
    let response = request.send().await.unwrap();
    assert_eq!(response.status(), 201);
    response.json().await.unwrap()
}

/// (8) An import sent again with its `Idempotency-Key` (its answer lost, or a 408) is answered
/// as the first was and stores nothing twice, sent after it or at the same moment; another key,
/// or none, is another import.
#[tokio::test]
async fn an_import_sent_again_with_its_idempotency_key_is_stored_once() {
    let proxy = spawn_proxy().await;
    let source = proxy.create_session().await;
    let a = proxy.done_stroke(&source, 300).await;
    proxy.done_stroke(&source, 200).await;
    assert_eq!(proxy.build_mesh(&source, a).send().await.unwrap().status(), 200);
    let path = format!("/v1/sessions/{}/export?format=glb", source.session);
    let glb = proxy.get(&path, &source).send().await.unwrap().bytes().await.unwrap().to_vec();
    let target = proxy.create_session().await;
    let strokes = |target: &TestSession| {
        let sql = format!("SELECT COUNT(*) FROM strokes WHERE session_id = '{}'", target.session);
        let db = &proxy.db;
        async move { count_rows(db, &sql).await }
    };

    let first = import(&proxy, &target, &glb, Some("import-1")).await;
    assert_eq!(first["strokes"].as_array().unwrap().len(), 2);
    assert_eq!(import(&proxy, &target, &glb, Some("import-1")).await, first);
    assert_eq!(strokes(&target).await, 2, "the retry stored nothing");
    // Two at once with a new key: one import.
    let (x, y) = tokio::join!(
        import(&proxy, &target, &glb, Some("import-2")),
        import(&proxy, &target, &glb, Some("import-2")),
    );
    assert_eq!(x, y);
    assert_ne!(x, first);
    assert_eq!(strokes(&target).await, 4);
    // Without a key, each request is an import; the same key from another participant too.
    import(&proxy, &target, &glb, None).await;
    import(&proxy, &target.stranger(), &glb, Some("import-1")).await;
    assert_eq!(strokes(&target).await, 8);
}

/// (3) Pages of stroke histories (placements, and solids since issue 51: one mechanism) are
/// read `MAX_HISTORY_READS` at a time on a replica: with every permit held a read waits its
/// turn (1 s here), then is 503 `busy`; one freed meanwhile lets it through.
#[tokio::test]
async fn stroke_history_reads_take_turns() {
    let proxy = spawn_proxy_with(|c| c.request_timeout_secs = 2).await;
    let session = proxy.create_session().await;
    let stroke = proxy.done_stroke(&session, 200).await;
    let path = format!("/v1/strokes/{stroke}/placements");
    let mut held = Vec::new();
    for _ in 0..penmesh_proxy::MAX_HISTORY_READS {
        held.push(proxy.state.history_read_permit(Duration::ZERO).await.unwrap());
    }
    for path in [path.clone(), format!("/v1/strokes/{stroke}/solids")] {
        let asked = Instant::now();
        let response = proxy.get(&path, &session).send().await.unwrap();
        assert_eq!(response.status(), 503, "{path}");
        assert!(asked.elapsed() >= Duration::from_millis(900), "it waited its turn first");
    }
    let freed = async {
        tokio::time::sleep(Duration::from_millis(300)).await;
        held.pop();
    };
    let (response, ()) = tokio::join!(proxy.get(&path, &session).send(), freed);
    assert_eq!(response.unwrap().status(), 200);
}
