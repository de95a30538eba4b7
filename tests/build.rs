//! Compiles the PostgreSQL-only tests in when `PENMESH_TEST_POSTGRES_URL` is set, and marks
//! them ignored otherwise: a run without PostgreSQL says they were not run instead of passing
//! them green, and a run with it fails them when PostgreSQL does not work.

fn main() {
    println!("cargo::rustc-check-cfg=cfg(penmesh_postgres)");
    println!("cargo::rerun-if-env-changed=PENMESH_TEST_POSTGRES_URL");
    if std::env::var("PENMESH_TEST_POSTGRES_URL").is_ok_and(|url| !url.is_empty()) {
        println!("cargo::rustc-cfg=penmesh_postgres");
    }
}
