//! Builds the browser page (`client/web/`) with Node: `npm ci` when its dependencies are not
//! installed yet (or the lock file changed), then its bundler (`client/web/build.mjs`) into
//! `OUT_DIR/web`, which `src/web.rs` embeds. Without Node and npm the build stops and says so.

use std::path::{Path, PathBuf};
use std::process::Command;

fn main() {
    let manifest = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").expect("CARGO_MANIFEST_DIR"));
    let web = manifest.join("../client/web");
    let out = PathBuf::from(std::env::var("OUT_DIR").expect("OUT_DIR")).join("web");
    // `sqlx::migrate!` embeds the files of `migrations/`: adding one must rebuild the proxy
    // (what `sqlx migrate build-script` writes).
    println!("cargo:rerun-if-changed=../migrations");
    for path in ["src", "build.mjs", "package.json", "package-lock.json"] {
        println!("cargo:rerun-if-changed={}", web.join(path).display());
    }
    let lock = web.join("package-lock.json");
    let installed = web.join("node_modules/.package-lock.json");
    if !installed.exists() || modified(&lock) > modified(&installed) {
        run(
            Command::new("npm").args(["ci", "--no-audit", "--no-fund"]).current_dir(&web),
            "npm ci",
        );
    }
    run(Command::new("node").arg("build.mjs").arg(&out).current_dir(&web), "node build.mjs");
}

fn modified(path: &Path) -> std::time::SystemTime {
    std::fs::metadata(path).and_then(|m| m.modified()).unwrap_or(std::time::UNIX_EPOCH)
}

fn run(command: &mut Command, what: &str) {
    match command.status() {
        Ok(status) if status.success() => {}
        Ok(status) => panic!(
            "building the browser page (client/web): `{what}` failed ({status}); run it in \
             client/web to see why"
        ),
        Err(err) => panic!(
            "building the browser page (client/web) needs Node.js and npm on the PATH: `{what}` \
             could not start ({err}). Install Node.js 18 or newer (with npm), then build again."
        ),
    }
}
