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
    restrict_to_owner(prefix);
    Ok(node)
}

/// iceoryx2 creates its global management segment world-writable (0666); every other file of
/// a deployment is the user's alone. Closes that: no file of the prefix stays writable by
/// other users. (Isolation between users, not between one user's processes.)
fn restrict_to_owner(prefix: &str) {
    use std::os::unix::fs::PermissionsExt;
    for p in prefixed_in(std::path::Path::new("/dev/shm"), prefix) {
        if let Ok(meta) = std::fs::metadata(&p) {
            let mode = meta.permissions().mode();
            if mode & 0o066 != 0 {
                let _ =
                    std::fs::set_permissions(&p, std::fs::Permissions::from_mode(mode & !0o077));
            }
        }
    }
}

/// Everything of a deployment on the machine: its entries in `/dev/shm` (shared memory, and
/// its services' checkpoints), those at the top of iceoryx2's root path (`/tmp/iceoryx2` by
/// default: event sockets), and the node and service directories under it that hold its files.
/// The one listing the report, `glint clean`, the tests and CI use.
pub fn shm_entries(prefix: &str) -> Vec<std::path::PathBuf> {
    let mut out = prefixed_in(std::path::Path::new("/dev/shm"), prefix);
    let root = Config::global_config().global.root_path().to_string();
    out.extend(prefixed_in(std::path::Path::new(&root), prefix));
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

/// The deployment prefixes (`glint_<hex>_`) that have anything in `/dev/shm` or in iceoryx2's
/// node and service directories, sorted.
pub fn glint_prefixes() -> Vec<String> {
    set_log_level_from_env_or(LogLevel::Error);
    let root = Config::global_config().global.root_path().to_string();
    let mut dirs = vec![
        std::path::PathBuf::from("/dev/shm"),
        std::path::PathBuf::from(&root),
    ];
    for sub in ["nodes", "services"] {
        let dir = std::path::Path::new(&root).join(sub);
        if let Ok(rd) = std::fs::read_dir(&dir) {
            dirs.extend(rd.flatten().map(|e| e.path()).filter(|p| p.is_dir()));
        }
        dirs.push(dir);
    }
    let mut out: Vec<String> = dirs
        .iter()
        .filter_map(|d| std::fs::read_dir(d).ok())
        .flat_map(|rd| rd.flatten())
        .filter_map(|e| deployment_prefix(&e.file_name().to_string_lossy()).map(str::to_string))
        .collect();
    out.sort();
    out.dedup();
    out
}

/// Whether `prefix` is a whole deployment prefix, `glint_<hex>_`.
pub fn is_deployment_prefix(prefix: &str) -> bool {
    deployment_prefix(prefix) == Some(prefix)
}

/// `glint_<hex>_` at the start of a file name.
fn deployment_prefix(name: &str) -> Option<&str> {
    let rest = name.strip_prefix("glint_")?;
    let hex = rest.find('_')?;
    (hex > 0 && rest[..hex].bytes().all(|b| b.is_ascii_hexdigit()))
        .then(|| &name[.."glint_".len() + hex + 1])
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
/// iceoryx2's node and service directories ([`shm_entries`]). A prefix that a live node still
/// holds (a process outside the deployment, or one not yet ended) keeps its files: they are
/// that node's, and show as leftovers. Call after every process of the deployment has exited.
/// Returns the number of entries removed and the names of the live nodes.
pub fn remove_shm(prefix: &str) -> (usize, Vec<String>) {
    let mut n = 0;
    let mut alive = vec![];
    if let Ok(name) = FileName::new(prefix.as_bytes()) {
        let mut config = Config::global_config().clone();
        config.global.prefix = name;
        let _ = Node::<ipc::Service>::list(&config, |state| {
            match state {
                NodeState::Dead(view) => {
                    n += view.try_remove_stale_resources().is_ok() as usize;
                }
                NodeState::Alive(view) => alive.push(node_label(&view)),
                // Another user's node: not ours to remove.
                NodeState::Inaccessible(id) => alive.push(format!("{id:?}")),
                // A node killed while it was being created: its files go below.
                NodeState::Undefined(_) => {}
            }
            CallbackProgression::Continue
        });
    }
    if !alive.is_empty() {
        return (n, alive);
    }
    for p in shm_entries(prefix) {
        let ok = if p.is_dir() {
            std::fs::remove_dir_all(&p).is_ok()
        } else {
            std::fs::remove_file(&p).is_ok()
        };
        n += ok as usize;
    }
    (n, alive)
}

/// What ended deployments left behind: [`shm_entries`] of every `glint_<hex>_` prefix that no
/// live node holds (a deployment still running is not a leftover).
pub fn leftovers() -> Vec<std::path::PathBuf> {
    glint_prefixes()
        .into_iter()
        .filter(|p| live_nodes(p).is_empty())
        .flat_map(|p| shm_entries(&p))
        .collect()
}

/// The live nodes under `prefix`: each one's name (or id, where it published no details) and
/// the pid of the process that created it. Another user's node is listed with no pid.
pub fn live_nodes(prefix: &str) -> Vec<(String, Option<u32>)> {
    use iceoryx2::node::NodeView;
    let mut out = vec![];
    let Ok(name) = FileName::new(prefix.as_bytes()) else {
        return out;
    };
    set_log_level_from_env_or(LogLevel::Error);
    let mut config = Config::global_config().clone();
    config.global.prefix = name;
    let _ = Node::<ipc::Service>::list(&config, |state| {
        match state {
            NodeState::Alive(view) => {
                let pid = view
                    .id()
                    .pid::<ipc::Service>()
                    .ok()
                    .and_then(|p| u32::try_from(p.value()).ok());
                out.push((node_label(&view), pid));
            }
            NodeState::Inaccessible(id) => out.push((format!("{id:?}"), None)),
            NodeState::Dead(_) | NodeState::Undefined(_) => {}
        }
        CallbackProgression::Continue
    });
    out
}

/// A live node's name, or its id where it published no details.
fn node_label(view: &impl iceoryx2::node::NodeView) -> String {
    view.details().as_ref().map_or_else(
        || format!("{:?}", view.id()),
        |d| d.name().as_str().to_string(),
    )
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

#[cfg(test)]
mod tests {
    use super::deployment_prefix;

    #[test]
    fn a_deployment_prefix_is_glint_hex_underscore() {
        assert_eq!(
            deployment_prefix("glint_4f2a09bc_frame.service"),
            Some("glint_4f2a09bc_")
        );
        assert_eq!(deployment_prefix("glint_4f2a09bc"), None);
        assert_eq!(deployment_prefix("glint__x"), None);
        assert_eq!(deployment_prefix("glint_xyz_a"), None);
        assert_eq!(deployment_prefix("iox2_4f2a_"), None);
        assert!(super::is_deployment_prefix("glint_4f2a09bc_"));
        assert!(!super::is_deployment_prefix("glint_4f2a09bc_x"));
        assert!(!super::is_deployment_prefix(""));
    }
}
