use penmesh_proxy::{Application, Config};

#[tokio::main]
async fn main() -> anyhow::Result<()> {
    penmesh_proxy::init_tracing();
    let config = Config::load()?;
    Application::build(config).await?.run_until_stopped().await
}
