//! PostgreSQL only (ignored without `PENMESH_TEST_POSTGRES_URL`, failing when it is set and
//! they cannot run): stroke locks a client cannot aim, and the database over TLS.

use std::path::Path;
use std::process::Stdio;
use std::time::Duration;

use penmesh_e2e::{
    TIMEOUT, TestDatabase, draw_stroke, spawn_proxy, spawn_proxy_on, stroke_samples,
};
use sqlx::Connection;
use uuid::Uuid;

/// Stroke ids are the client's choice. The stroke lock's key must not be one the client can
/// aim at another lock: before, the key was `hi ^ lo` of the id in the one-`bigint` key space
/// where the replicas' and sqlx's migration locks live, so the id `(K, 0)` took lock `K`.
#[tokio::test]
#[cfg_attr(not(penmesh_postgres), ignore = "needs PostgreSQL: set PENMESH_TEST_POSTGRES_URL")]
async fn a_stroke_id_cannot_take_or_wait_for_another_advisory_lock() {
    let proxy = spawn_proxy().await;
    assert!(proxy.db.is_postgres());
    let session = proxy.create_session().await;
    let mut other = sqlx::PgConnection::connect(&proxy.db.url).await.unwrap();
    for (case, key, held_by_other) in [
        ("a lock someone else holds", 0x1234_5678_9abc_def0_i64, true),
        ("a free lock", 0x0fed_cba9_8765_4321_i64, false),
    ] {
        if held_by_other {
            let ok: bool = sqlx::query_scalar("SELECT pg_try_advisory_lock($1)")
                .bind(key)
                .fetch_one(&mut other)
                .await
                .unwrap();
            assert!(ok, "{case}");
        }
        let stroke = Uuid::from_u64_pair(key as u64, 0);
        // Begun and acknowledged: the stroke's lock is not `key`, so nothing waits for it.
        let mut ws = proxy.drawing(&session, stroke).await;
        if !held_by_other {
            // And while the stroke is open, `key` is free for whoever needs it.
            let ok: bool = sqlx::query_scalar("SELECT pg_try_advisory_lock($1)")
                .bind(key)
                .fetch_one(&mut other)
                .await
                .unwrap();
            assert!(ok, "{case}: the open stroke holds lock {key}");
        }
        ws.end(stroke, 0).await;
        ws.recv_until(|m| matches!(m, penmesh::protocol::ServerMessage::StrokeDone(_))).await;
    }
}

/// Runs `program` with `args`, as the `postgres` user when this process is root (initdb and
/// postgres refuse to run as root).
fn as_postgres(program: &Path, args: &[&str]) -> std::process::Command {
    let root = running_as_root();
    let mut command = if root {
        let mut c = std::process::Command::new("runuser");
        c.args(["-u", "postgres", "--"]).arg(program);
        c
    } else {
        std::process::Command::new(program)
    };
    command.args(args);
    command
}

fn running_as_root() -> bool {
    let out = std::process::Command::new("id").arg("-u").output().expect("id -u");
    String::from_utf8_lossy(&out.stdout).trim() == "0"
}

/// sqlx is built with rustls: a `sslmode=require` URL reaches a server that accepts only TLS.
/// The server is a throwaway PostgreSQL started here (the machine's own is not configured for
/// TLS), with a certificate made here, and a `pg_hba.conf` that refuses connections without TLS.
#[tokio::test]
#[cfg_attr(not(penmesh_postgres), ignore = "needs PostgreSQL: set PENMESH_TEST_POSTGRES_URL")]
async fn the_proxy_reaches_postgresql_over_tls_with_sslmode_require() {
    let bin = Path::new("/usr/lib/postgresql/15/bin");
    assert!(bin.join("initdb").exists(), "PostgreSQL 15's initdb is needed at {}", bin.display());
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path();
    // The server runs as `postgres`: it must reach the folder and own its files.
    std::fs::set_permissions(root, std::os::unix::fs::PermissionsExt::from_mode(0o777)).unwrap();
    let data = root.join("data");
    let status = as_postgres(
        &bin.join("initdb"),
        &["-D", data.to_str().unwrap(), "-U", "postgres", "-A", "trust", "--no-sync"],
    )
    .stdout(Stdio::null())
    .status()
    .unwrap();
    assert!(status.success(), "initdb failed");
    // Certificate and key, written by the server's user (PostgreSQL checks the key's owner).
    let cert =
        rcgen::generate_simple_self_signed(vec!["localhost".into(), "127.0.0.1".into()]).unwrap();
    for (name, pem) in
        [("server.crt", cert.cert.pem()), ("server.key", cert.signing_key.serialize_pem())]
    {
        let path = data.join(name);
        let mut tee = as_postgres(Path::new("/usr/bin/tee"), &[path.to_str().unwrap()])
            .stdin(Stdio::piped())
            .stdout(Stdio::null())
            .spawn()
            .unwrap();
        std::io::Write::write_all(tee.stdin.as_mut().unwrap(), pem.as_bytes()).unwrap();
        drop(tee.stdin.take());
        assert!(tee.wait().unwrap().success());
        let status = as_postgres(Path::new("/bin/chmod"), &["600", path.to_str().unwrap()])
            .status()
            .unwrap();
        assert!(status.success());
    }
    let hba = "local all all trust\nhostssl all all 127.0.0.1/32 trust\n";
    let status = as_postgres(
        Path::new("/bin/sh"),
        &[
            "-c",
            &format!(
                "printf '{}' > {}",
                hba.replace('\n', "\\n"),
                data.join("pg_hba.conf").display()
            ),
        ],
    )
    .status()
    .unwrap();
    assert!(status.success());
    let port = std::net::TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port();
    let port_text = port.to_string();
    let socket_dir = format!("unix_socket_directories={}", root.display());
    let server = as_postgres(
        &bin.join("postgres"),
        &[
            "-D",
            data.to_str().unwrap(),
            "-p",
            &port_text,
            "-c",
            "listen_addresses=127.0.0.1",
            "-c",
            &socket_dir,
            "-c",
            "ssl=on",
            "-c",
            "ssl_cert_file=server.crt",
            "-c",
            "ssl_key_file=server.key",
            "-c",
            "fsync=off",
        ],
    )
    .stdout(Stdio::null())
    .stderr(Stdio::null())
    .spawn()
    .unwrap();
    let _server = StopOnDrop { runuser: server, pid_file: data.join("postmaster.pid") };

    let tls = format!("postgres://postgres@127.0.0.1:{port}/postgres?sslmode=require");
    let deadline = tokio::time::Instant::now() + TIMEOUT;
    loop {
        match sqlx::PgConnection::connect(&tls).await {
            Ok(conn) => {
                let _ = conn.close().await;
                break;
            }
            Err(err) if tokio::time::Instant::now() > deadline => {
                panic!("the TLS PostgreSQL did not come up: {err}")
            }
            Err(_) => tokio::time::sleep(Duration::from_millis(100)).await,
        }
    }
    // The server takes TLS only: without it the connection is refused.
    let plain = format!("postgres://postgres@127.0.0.1:{port}/postgres?sslmode=disable");
    let Err(err) = sqlx::PgConnection::connect(&plain).await else {
        panic!("a connection without TLS was let in");
    };
    assert!(
        err.to_string().contains("no encryption") || err.to_string().contains("pg_hba"),
        "{err}"
    );

    // The proxy on that server: it migrates, and a stroke goes in and comes back.
    let db = TestDatabase::existing(tls);
    let proxy = spawn_proxy_on(db, |_| {}).await;
    let session = proxy.create_session().await;
    let mut ws = proxy.connect(&session).await;
    ws.hello(vec![]).await;
    let stroke = Uuid::new_v4();
    let samples = stroke_samples(30);
    draw_stroke(&mut ws, stroke, &samples, 10).await;
    assert_eq!(proxy.raw_samples(&session, stroke).await, samples);
    proxy.stop().await;
}

/// Stops the throwaway server (fast shutdown: SIGINT to the postmaster, whose pid is the first
/// line of `postmaster.pid`), then reaps the process started here.
struct StopOnDrop {
    runuser: std::process::Child,
    pid_file: std::path::PathBuf,
}

impl Drop for StopOnDrop {
    fn drop(&mut self) {
        let pid = std::fs::read_to_string(&self.pid_file)
            .ok()
            .and_then(|text| text.lines().next().map(|line| line.trim().to_string()));
        let pid = pid.unwrap_or_else(|| self.runuser.id().to_string());
        let _ = std::process::Command::new("kill").args(["-INT", &pid]).status();
        let _ = self.runuser.wait();
    }
}
