//! Two replicas on one PostgreSQL database. Built as ignored tests when
//! `PENMESH_TEST_POSTGRES_URL` was not set at compile time (see `tests/build.rs`), so a run
//! without PostgreSQL lists them as not run; with it set they run, and fail when PostgreSQL does.

use std::time::Duration;

use penmesh::protocol::StrokeStatus;
use penmesh_proxy::LISTENER_APPLICATION;
use sqlx::Connection;
use uuid::Uuid;

use crate::helpers::{
    Participant, check_complete, expected_view, put_mesh, samples_for, two_replicas,
};

#[tokio::test]
#[cfg_attr(not(penmesh_postgres), ignore = "needs PostgreSQL: set PENMESH_TEST_POSTGRES_URL")]
async fn participants_on_two_replicas_see_each_others_strokes_and_meshes_in_order() {
    let (a, b) = two_replicas().await;
    let session = a.create_session().await;
    let mut on_a = Participant::join(&a, &session, "on A").await;
    let mut on_b = Participant::join(&b, &session, "on B").await;
    let strokes_a: Vec<_> = (0..3).map(|k| (Uuid::new_v4(), samples_for(k, 150))).collect();
    let strokes_b: Vec<_> = (3..6).map(|k| (Uuid::new_v4(), samples_for(k, 150))).collect();

    // Act: both draw at once; each mesh is stored through the other replica's HTTP API.
    tokio::join!(
        async {
            for (stroke, samples) in &strokes_a {
                on_a.draw(*stroke, samples, 5).await;
                put_mesh(&b, &on_a, &session, *stroke).await;
            }
        },
        async {
            for (stroke, samples) in &strokes_b {
                on_b.draw(*stroke, samples, 9).await;
                put_mesh(&a, &on_b, &session, *stroke).await;
            }
        }
    );
    on_a.wait_for(|v| v.n_meshes() == 3).await;
    on_b.wait_for(|v| v.n_meshes() == 3).await;

    // Assert (the views check order and repeats as events arrive).
    let all: Vec<_> = strokes_a.iter().chain(&strokes_b).cloned().collect();
    let meshes: Vec<Uuid> = all.iter().map(|(id, _)| *id).collect();
    let expected = expected_view(&all, &meshes);
    check_complete(&on_a, &expected);
    check_complete(&on_b, &expected);
    assert_eq!(on_b.view.present[&on_a.welcome.participant], "on A");
}

#[tokio::test]
#[cfg_attr(not(penmesh_postgres), ignore = "needs PostgreSQL: set PENMESH_TEST_POSTGRES_URL")]
async fn a_replica_killed_mid_stroke_is_resumed_on_the_other_and_everyone_ends_equal() {
    let (a, b) = two_replicas().await;
    let session = b.create_session().await;
    let mut watcher = Participant::join(&b, &session, "watcher").await;
    let mut drawer = Participant::join(&a, &session, "drawer").await;
    let (finished, cut) = (Uuid::new_v4(), Uuid::new_v4());
    let (finished_samples, cut_samples) = (samples_for(1, 160), samples_for(2, 300));
    drawer.draw(finished, &finished_samples, 8).await;
    drawer.begin(cut).await;
    drawer.send_points(cut, &cut_samples, 0, 120, 6).await;
    drawer.wait_ack(cut, 120).await;
    drawer.send_points(cut, &cut_samples, 120, 160, 6).await;
    watcher.wait_for(|v| v.n_done() == 1 && v.strokes.contains_key(&cut)).await;

    // Act: replica A crashes; the drawer reconnects to B and resumes the stroke.
    let old_drawer = drawer.welcome.participant;
    assert!(watcher.view.present.contains_key(&old_drawer));
    let db = a.kill();
    let key = drawer.key.clone();
    drop(drawer);
    let mut drawer =
        Participant::join_resuming(&b, &session, "drawer again", &key, vec![cut]).await;
    assert_eq!(drawer.welcome.participant, old_drawer, "the same key: the same participant");
    let resume = drawer.welcome.resume[0].clone();
    // `interrupted` once a reaper round has seen A's lock gone and nobody drawing it (a race
    // with this resume), `open` before that: resumable either way.
    assert!(matches!(resume.status, StrokeStatus::Open | StrokeStatus::Interrupted), "{resume:?}");
    let next = resume.next_seq as usize;
    assert!((120..=160).contains(&next), "resumes from {next}");
    drawer.send_points(cut, &cut_samples, next, 300, 6).await;
    drawer.wait_ack(cut, 300).await;
    drawer.finish(cut, 300).await;
    put_mesh(&b, &drawer, &session, cut).await;

    // Assert: the watcher, the drawer and a late joiner end with the same, complete session.
    let expected = expected_view(&[(finished, finished_samples), (cut, cut_samples)], &[cut]);
    watcher.wait_for(|v| v.n_done() == 2 && v.n_meshes() == 1).await;
    check_complete(&watcher, &expected);
    check_complete(&drawer, &expected);
    // The crashed replica's connection is noticed gone (its replica's lock went with it), but
    // the drawer is still here on B: nobody hears it leave.
    let start = std::time::Instant::now();
    let closed = "SELECT COUNT(*) FROM participants WHERE left_at IS NOT NULL";
    while penmesh_e2e::count_rows(&db, closed).await < 1 {
        assert!(start.elapsed() < penmesh_e2e::TIMEOUT, "the dead replica's rows stay open");
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    let late = Participant::join(&b, &session, "late").await;
    check_complete(&late, &expected);
    assert_eq!(late.view.strokes, watcher.view.strokes);
    assert!(late.view.present.contains_key(&old_drawer));
    // The late joiner's arrival comes after the reaper's commit.
    let late_id = late.welcome.participant;
    watcher.wait_for(|v| v.present.contains_key(&late_id)).await;
    assert!(watcher.view.present.contains_key(&old_drawer));
    drop(db);
}

#[tokio::test]
#[cfg_attr(not(penmesh_postgres), ignore = "needs PostgreSQL: set PENMESH_TEST_POSTGRES_URL")]
async fn a_lost_listener_connection_resyncs_its_sessions_from_the_database() {
    let (a, b) = two_replicas().await;
    let session = a.create_session().await;
    let mut watcher = Participant::join(&a, &session, "watcher").await;
    let mut drawer = Participant::join(&b, &session, "drawer").await;
    let strokes: Vec<_> = (0..8).map(|k| (Uuid::new_v4(), samples_for(k, 150))).collect();

    // Act: while B's participant draws, every listener connection of the database is cut.
    tokio::join!(
        async {
            for (stroke, samples) in &strokes {
                drawer.draw(*stroke, samples, 5).await;
            }
        },
        async {
            tokio::time::sleep(Duration::from_millis(80)).await;
            let mut admin = sqlx::PgConnection::connect(&a.db.url).await.unwrap();
            let cut: Vec<bool> = sqlx::query_scalar(
                "SELECT pg_terminate_backend(pid) FROM pg_stat_activity \
                 WHERE application_name = $1 AND datname = current_database()",
            )
            .bind(LISTENER_APPLICATION)
            .fetch_all(&mut admin)
            .await
            .unwrap();
            assert_eq!(cut.len(), 2, "one listener per replica");
        }
    );

    // Assert: the watcher was resynced (a second `Synced`) and has everything exactly once.
    watcher.wait_for(|v| v.n_done() == strokes.len() && v.n_synced >= 2).await;
    check_complete(&watcher, &expected_view(&strokes, &[]));
}
