use penmesh_proxy::Config;

/// mimalloc rather than the system allocator, as in the `penmesh` binary (see there).
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

fn main() -> anyhow::Result<()> {
    penmesh_proxy::init_tracing();
    penmesh_proxy::run(Config::load()?)
}
