//! Node creation under a per-deployment prefix, shared-memory housekeeping, tracing.

use anyhow::{anyhow, Context, Result};
use iceoryx2::prelude::*;
use shared_types::topics::IpcNode;

/// Creates the iceoryx2 node of one process. Every service of a deployment uses the same
/// `prefix` (e.g. `glint_4f2a_`), which isolates its shared memory from any other deployment.
/// Node creation also cleans up resources of dead nodes of the same prefix (a restart).
pub fn open_node(prefix: &str, name: &str) -> Result<IpcNode> {
    set_log_level_from_env_or(LogLevel::Error);
    let mut config = Config::global_config().clone();
    config.global.prefix = FileName::new(prefix.as_bytes())
        .map_err(|e| anyhow!("invalid prefix '{prefix}': {e:?}"))?;
    let node_name =
        NodeName::new(name).map_err(|e| anyhow!("invalid node name '{name}': {e:?}"))?;
    let node = NodeBuilder::new()
        .name(&node_name)
        .config(&config)
        .create::<ipc::Service>()
        .map_err(|e| anyhow!("{e:?}"))
        .with_context(|| format!("creating iceoryx2 node '{name}' with prefix '{prefix}'"))?;
    node.try_cleanup_dead_nodes();
    Ok(node)
}

/// Entries in `/dev/shm` that belong to a prefix.
pub fn shm_entries(prefix: &str) -> Vec<std::path::PathBuf> {
    let mut out = vec![];
    if let Ok(dir) = std::fs::read_dir("/dev/shm") {
        for e in dir.flatten() {
            if e.file_name().to_string_lossy().starts_with(prefix) {
                out.push(e.path());
            }
        }
    }
    out.sort();
    out
}

/// Removes a prefix's leftovers from `/dev/shm` and iceoryx2's node/service directories.
/// Call only after every process of the deployment has exited.
pub fn remove_shm(prefix: &str) -> usize {
    let mut n = 0;
    for p in shm_entries(prefix) {
        if std::fs::remove_file(&p).is_ok() {
            n += 1;
        }
    }
    let root = Config::global_config().global.root_path().to_string();
    for sub in ["nodes", "services"] {
        let dir = std::path::Path::new(&root).join(sub);
        n += remove_prefixed(&dir, prefix);
    }
    n
}

fn remove_prefixed(dir: &std::path::Path, prefix: &str) -> usize {
    let mut n = 0;
    if let Ok(rd) = std::fs::read_dir(dir) {
        for e in rd.flatten() {
            if !e.file_name().to_string_lossy().starts_with(prefix) {
                continue;
            }
            let p = e.path();
            let ok = if p.is_dir() {
                std::fs::remove_dir_all(&p).is_ok()
            } else {
                std::fs::remove_file(&p).is_ok()
            };
            n += ok as usize;
        }
    }
    n
}

/// Sets up `tracing` to stderr, filtered by `RUST_LOG` (default `info`), with the service name.
pub fn init_tracing(service: &str) {
    let filter = tracing_subscriber::EnvFilter::try_from_default_env()
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info"));
    let _ = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
        .with_target(false)
        .try_init();
    tracing::debug!(service, "tracing ready");
}
