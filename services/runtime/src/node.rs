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

/// What a prefix left behind: its entries in `/dev/shm`, and the node and service
/// directories under iceoryx2's root path (`/tmp/iceoryx2` by default) that hold its files.
pub fn shm_entries(prefix: &str) -> Vec<std::path::PathBuf> {
    let mut out = prefixed_in(std::path::Path::new("/dev/shm"), prefix);
    let root = Config::global_config().global.root_path().to_string();
    for sub in ["nodes", "services"] {
        let dir = std::path::Path::new(&root).join(sub);
        out.extend(prefixed_in(&dir, prefix));
        // A node's directory is named by its id; its files carry the prefix.
        if let Ok(rd) = std::fs::read_dir(&dir) {
            for e in rd.flatten() {
                let p = e.path();
                if p.is_dir() && !prefixed_in(&p, prefix).is_empty() {
                    out.push(p);
                }
            }
        }
    }
    out.sort();
    out.dedup();
    out
}

/// Entries of `dir` whose name starts with `prefix`.
fn prefixed_in(dir: &std::path::Path, prefix: &str) -> Vec<std::path::PathBuf> {
    let Ok(rd) = std::fs::read_dir(dir) else {
        return vec![];
    };
    rd.flatten()
        .filter(|e| e.file_name().to_string_lossy().starts_with(prefix))
        .map(|e| e.path())
        .collect()
}

/// Removes a prefix's leftovers: first iceoryx2's own cleanup of the prefix's dead nodes
/// (their stale ports and services), then whatever of the prefix remains in `/dev/shm` and in
/// iceoryx2's node and service directories ([`shm_entries`]). Call only after every process
/// of the deployment has exited. Returns the number of entries removed.
pub fn remove_shm(prefix: &str) -> usize {
    let mut n = 0;
    if let Ok(name) = FileName::new(prefix.as_bytes()) {
        let mut config = Config::global_config().clone();
        config.global.prefix = name;
        let _ = Node::<ipc::Service>::list(&config, |state| {
            if let NodeState::Dead(view) = state {
                n += view.try_remove_stale_resources().is_ok() as usize;
            }
            CallbackProgression::Continue
        });
    }
    for p in shm_entries(prefix) {
        let ok = if p.is_dir() {
            std::fs::remove_dir_all(&p).is_ok()
        } else {
            std::fs::remove_file(&p).is_ok()
        };
        n += ok as usize;
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
