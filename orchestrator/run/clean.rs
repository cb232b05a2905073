//! `glint clean`: remove what crashed deployments left in shared memory — iceoryx2's own
//! cleanup of dead nodes first, then the prefix's remaining files in `/dev/shm` and in
//! iceoryx2's node and service directories. A prefix a live process still holds (a running
//! deployment, an observer) is left in place and named.

use glint_runtime::{glint_prefixes, remove_shm, shm_entries};

/// Cleans `prefix`, or every `glint_<hex>_` prefix found; returns the lines to print.
pub fn clean(prefix: Option<&str>) -> Vec<String> {
    let prefixes = match prefix {
        Some(p) => vec![p.to_string()],
        None => glint_prefixes(),
    };
    let mut lines = vec![];
    let (mut removed_total, mut held) = (0, 0);
    for p in &prefixes {
        let (removed, alive) = remove_shm(p);
        removed_total += removed;
        if alive.is_empty() {
            let left = shm_entries(p).len();
            lines.push(match left {
                0 => format!("{p}: {removed} entries removed"),
                n => format!("{p}: {removed} entries removed, {n} could not be removed"),
            });
        } else {
            held += 1;
            lines.push(format!(
                "{p}: in use by live node(s) {}; left in place",
                alive.join(", ")
            ));
        }
    }
    lines.insert(
        0,
        format!(
            "cleaned {} deployment prefix(es): {removed_total} entries removed{}",
            prefixes.len() - held,
            if held > 0 {
                format!(", {held} in use and left in place")
            } else {
                String::new()
            }
        ),
    );
    lines
}

/// `glint clean [--prefix P | --list]`.
pub fn command(prefix: Option<String>, list: bool) -> std::process::ExitCode {
    use std::process::ExitCode;
    if list {
        for p in glint_runtime::leftovers() {
            println!("{}", p.display());
        }
        return ExitCode::SUCCESS;
    }
    if let Some(p) = prefix
        .as_deref()
        .filter(|p| !glint_runtime::is_deployment_prefix(p))
    {
        eprintln!("error: --prefix {p:?}: a deployment prefix is glint_<hex digits>_ (report.json, run.prefix)");
        return ExitCode::from(2);
    }
    for line in clean(prefix.as_deref()) {
        println!("{line}");
    }
    ExitCode::SUCCESS
}
