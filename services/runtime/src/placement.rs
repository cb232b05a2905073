//! Pinning a process to the CPU its scenario gives it (`[services.<name>] cpu`).

use anyhow::{bail, Context, Result};
use rustix::thread::{sched_getaffinity, sched_setaffinity, CpuSet};

/// The CPUs this process may run on (its affinity mask), ascending.
pub fn allowed_cpus() -> Vec<u32> {
    match sched_getaffinity(None) {
        Ok(set) => (0..CpuSet::MAX_CPU)
            .filter(|&i| set.is_set(i))
            .map(|i| i as u32)
            .collect(),
        Err(_) => vec![],
    }
}

/// Pins the calling thread — and every thread it starts after — to `cpu`; an error if the
/// host does not give it that CPU. Returns the mask read back.
pub fn pin_to(cpu: u32) -> Result<Vec<u32>> {
    let allowed = allowed_cpus();
    if !allowed.contains(&cpu) {
        bail!("CPU {cpu} is not one this process may run on ({allowed:?})");
    }
    let mut set = CpuSet::new();
    set.set(cpu as usize);
    sched_setaffinity(None, &set).with_context(|| format!("pinning to CPU {cpu}"))?;
    Ok(allowed_cpus())
}

/// Pins the calling thread to `cpu` when one is given, and says so in the log.
pub fn apply(who: &str, cpu: Option<u32>) -> Result<()> {
    let Some(cpu) = cpu else {
        return Ok(());
    };
    let now = pin_to(cpu)?;
    tracing::info!(cpus = ?now, "{who} pinned to CPU {cpu}");
    Ok(())
}
