// `sqlx::migrate!` embeds the files of `migrations/` at compile time; without this, adding a
// migration file alone would not rebuild the proxy (what `sqlx migrate build-script` writes).
fn main() {
    println!("cargo:rerun-if-changed=../migrations");
}
