//! A full disk under SQLite: the proxy's file size limit (`RLIMIT_FSIZE`, with `SIGXFSZ`
//! ignored) drops to 0 mid-load, so every write to a file fails with `EFBIG` (SQLite says
//! "disk I/O error"); then it is lifted. The pens must be told why their samples are not
//! stored (in the proxy's words: the database's stay in its log), nothing unstored may be
//! acknowledged, and drawing must go on once space returns.

use std::time::{Duration, Instant};

use crate::check::{Load, assert_promises, verify};
use crate::child::ProxyChild;
use crate::{PENS, RECOVERY, plan};

/// How long the disk stays full.
const FULL: Duration = Duration::from_secs(3);

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_full_disk_under_sqlite_is_reported_and_drawing_resumes_when_space_returns() {
    let dir = tempfile::tempdir().unwrap();
    let url = format!("sqlite://{}", dir.path().join("penmesh.db").display());
    let proxy = ProxyChild::start(&url, &[]).await;
    let session = proxy.create_session().await;
    let load = Load::start(&proxy, &session, PENS, plan()).await;

    // Act
    proxy.set_file_size_limit(Some(0));
    tokio::time::sleep(FULL).await;
    proxy.set_file_size_limit(None);
    let freed = Instant::now();
    let (session, logs) = load.finish().await;

    // Assert
    let figures = verify(&proxy, &session, &logs, freed).await;
    println!("{}", figures.line(&format!("disk full {FULL:?} (sqlite)")));
    let failures: Vec<&String> = logs.iter().flat_map(|l| &l.failures).collect();
    // SQLite reports a write refused with EFBIG as a disk I/O error (a short write, or
    // ENOSPC, as "database or disk is full"): either way the pen is told why, in the proxy's
    // words, never the database's.
    let told = |f: &&String| f.contains("disk is full or failing");
    let leaked = |f: &&String| f.contains("disk I/O error") || f.contains("code: ");
    assert!(!failures.iter().any(leaked), "the database's words reached a pen: {failures:#?}");
    assert!(failures.iter().any(told), "the pens were told of the disk: {failures:#?}");
    assert_promises(&figures, RECOVERY);
}
