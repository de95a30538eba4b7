use penmesh_proxy::Config;

fn main() -> anyhow::Result<()> {
    penmesh_proxy::init_tracing();
    penmesh_proxy::run(Config::load()?)
}
