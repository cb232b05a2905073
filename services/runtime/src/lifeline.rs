//! What ends a process besides its work: SIGHUP (handled like SIGTERM, so a closed terminal
//! or an orphaned, stopped process group ends a run cleanly) and, for a service, the end of
//! the process that started it. The orchestrator spawns each service with a parent-death
//! signal (SIGTERM, [`set_death_signal_in_child`]); a service also checks on every wake of
//! its loop that its parent is still the one that started it, so no service outlives its
//! orchestrator even if the signal was missed.

use std::sync::atomic::{AtomicBool, AtomicI32, Ordering};
use std::sync::{Arc, OnceLock};

use rustix::process::{getppid, set_parent_process_death_signal, Pid, Signal};

/// Set by the SIGHUP handler.
static HANGUP: OnceLock<Arc<AtomicBool>> = OnceLock::new();
/// The parent this process watches (0: none).
static PARENT: AtomicI32 = AtomicI32::new(0);

/// Installs the SIGHUP handler once per process (iceoryx2 handles SIGINT and SIGTERM).
pub fn handle_hangup() {
    HANGUP.get_or_init(|| {
        let flag = Arc::new(AtomicBool::new(false));
        if let Err(e) = signal_hook::flag::register(signal_hook::consts::SIGHUP, flag.clone()) {
            tracing::warn!("SIGHUP handler not installed: {e}");
        }
        flag
    });
}

/// From now on, this process ends (as on SIGTERM) once its current parent is gone.
pub fn watch_parent() {
    PARENT.store(raw(getppid()), Ordering::SeqCst);
}

/// Why this process should end now, if it should: a SIGHUP, or a watched parent gone.
pub fn end_requested() -> Option<&'static str> {
    if HANGUP.get().is_some_and(|f| f.load(Ordering::SeqCst)) {
        return Some("SIGHUP");
    }
    let watched = PARENT.load(Ordering::SeqCst);
    (watched != 0 && raw(getppid()) != watched).then_some("the parent process ended")
}

/// For `CommandExt::pre_exec` in a spawned child: SIGTERM when the spawning thread ends; if
/// the parent `parent` already ended before the signal was armed, the exec is abandoned
/// (ESRCH) and the child exits. Only async-signal-safe calls: two syscalls, no allocation.
pub fn set_death_signal_in_child(parent: Pid) -> std::io::Result<()> {
    set_parent_process_death_signal(Some(Signal::TERM))?;
    if getppid() != Some(parent) {
        const ESRCH: i32 = 3;
        return Err(std::io::Error::from_raw_os_error(ESRCH));
    }
    Ok(())
}

fn raw(pid: Option<Pid>) -> i32 {
    pid.map_or(0, |p| p.as_raw_nonzero().get())
}
