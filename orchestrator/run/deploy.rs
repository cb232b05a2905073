//! Child processes: spawn `glint service <name>` in its own process group, watch it, and stop
//! it with the ladder Shutdown → grace → SIGTERM → grace → SIGKILL (a polled state machine).

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use anyhow::{Context, Result};
use rustix::process::{Pid, Signal};
use shared_types::ServiceId;

/// How a child ended.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Ending {
    Running,
    /// Exited by itself with this status (code or signal).
    Exited(String),
    /// Exited after the `Shutdown` control message.
    Shutdown,
    /// Needed SIGTERM.
    Terminated,
    /// Needed SIGKILL.
    Killed,
}

impl Ending {
    pub fn label(&self) -> String {
        match self {
            Ending::Running => "running".into(),
            Ending::Exited(s) => format!("exited ({s})"),
            Ending::Shutdown => "shutdown".into(),
            Ending::Terminated => "sigterm".into(),
            Ending::Killed => "sigkill".into(),
        }
    }
}

pub struct ServiceProcess {
    pub id: ServiceId,
    pub pid: u32,
    pub restarts: u32,
    pub ending: Ending,
    /// Set once it exited: whether with status 0.
    pub exit_ok: Option<bool>,
    /// Set once it exited with a status: its code.
    pub exit_code: Option<i32>,
    /// CPU time the process used (user + system) [s], read when it exited.
    pub cpu_s: Option<f64>,
    child: Option<Child>,
    pub log_path: PathBuf,
}

impl ServiceProcess {
    /// Spawns `exe service <name> --prefix P --scenario FILE [--host H]`; stderr goes to
    /// `logs/<name>.log`. `restarts` > 0: a restart by supervision (`--restarted`); its log is
    /// appended to. `host`: this host's name in a deployment split across hosts.
    pub fn spawn(
        exe: &Path,
        id: ServiceId,
        prefix: &str,
        scenario: &Path,
        log_dir: &Path,
        restarts: u32,
        host: Option<&str>,
    ) -> Result<Self> {
        use std::io::Write;
        use std::os::unix::process::CommandExt;
        std::fs::create_dir_all(log_dir)?;
        let log_path = log_dir.join(format!("{}.log", id.name()));
        let mut log = if restarts == 0 {
            std::fs::File::create(&log_path)
        } else {
            std::fs::OpenOptions::new()
                .append(true)
                .create(true)
                .open(&log_path)
        }
        .with_context(|| format!("creating {}", log_path.display()))?;
        if restarts > 0 {
            let _ = writeln!(log, "--- restart {restarts} ---");
        }
        let parent = rustix::process::getpid();
        let mut command = Command::new(exe);
        // SAFETY: the closure runs in the forked child before exec and makes only
        // async-signal-safe calls (prctl, getppid), allocating nothing.
        unsafe {
            command.pre_exec(move || glint_runtime::lifeline::set_death_signal_in_child(parent));
        }
        let child = command
            .arg("service")
            .arg(id.name())
            .arg("--prefix")
            .arg(prefix)
            .arg("--scenario")
            .arg(scenario)
            .args(if restarts > 0 {
                &["--restarted"][..]
            } else {
                &[]
            })
            .args(host.map(|h| ["--host", h]).into_iter().flatten())
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::from(log))
            .process_group(0)
            .spawn()
            .with_context(|| format!("spawning service {}", id.name()))?;
        Ok(ServiceProcess {
            id,
            pid: child.id(),
            restarts,
            ending: Ending::Running,
            exit_ok: None,
            exit_code: None,
            cpu_s: None,
            child: Some(child),
            log_path,
        })
    }

    /// Non-blocking: has the child exited? Records the ending the first time.
    pub fn poll_exit(&mut self) -> bool {
        let Some(child) = self.child.as_mut() else {
            return true;
        };
        // An exited child stays a zombie until reaped: its CPU times are read first.
        if self.cpu_s.is_none() && exited_unreaped(self.pid) {
            self.cpu_s = cpu_seconds(self.pid);
        }
        match child.try_wait() {
            Ok(Some(status)) => {
                self.exit_ok = Some(status.success());
                self.exit_code = status.code();
                if self.ending == Ending::Running {
                    self.ending = Ending::Exited(status.to_string());
                }
                self.child = None;
                true
            }
            Ok(None) => false,
            Err(_) => false,
        }
    }

    pub fn is_running(&mut self) -> bool {
        !self.poll_exit()
    }

    /// Sends `sig` to the child's process group (it was spawned with pgid = pid).
    pub fn signal(&self, sig: Signal) {
        if self.child.is_some() {
            signal_group(self.pid, sig);
        }
    }

    /// Last lines of the service's log, for error messages.
    pub fn log_tail(&self, lines: usize) -> String {
        let text = std::fs::read_to_string(&self.log_path).unwrap_or_default();
        let all: Vec<&str> = text.lines().collect();
        all[all.len().saturating_sub(lines)..].join("\n")
    }
}

impl Drop for ServiceProcess {
    /// Never leave a child behind, whatever path leads here.
    fn drop(&mut self) {
        if let Some(mut c) = self.child.take() {
            signal_group(self.pid, Signal::KILL);
            let _ = c.wait();
        }
    }
}

/// kill(2) on the process group `pgid`; a group that is already gone (ESRCH) is not an error.
fn signal_group(pgid: u32, sig: Signal) {
    if let Some(pid) = i32::try_from(pgid).ok().and_then(Pid::from_raw) {
        let _ = rustix::process::kill_process_group(pid, sig);
    }
}

/// Waits for every child to exit, polling every 5 ms, for at most `grace`; calls `while_waiting`
/// on each poll (the caller drains final heartbeats there).
fn wait_all(
    children: &mut [ServiceProcess],
    grace: Duration,
    while_waiting: &mut dyn FnMut(),
) -> bool {
    let t0 = Instant::now();
    loop {
        while_waiting();
        let all = children.iter_mut().all(|c| c.poll_exit());
        if all {
            return true;
        }
        if t0.elapsed() >= grace {
            return false;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
}

/// The stop ladder: `send_shutdown` publishes the `Shutdown` control message, then each rung
/// waits `grace` for the children still running, escalating to SIGTERM and SIGKILL. Each
/// child's ending records the rung that stopped it; which children are running is taken before
/// each rung starts (for the first, before `Shutdown` is sent, so a fast exit still counts as a
/// graceful one).
pub fn stop_ladder(
    children: &mut [ServiceProcess],
    grace: Duration,
    send_shutdown: &mut dyn FnMut(),
    while_waiting: &mut dyn FnMut(),
) {
    let rungs = [
        (None, Ending::Shutdown),
        (Some(Signal::TERM), Ending::Terminated),
        (Some(Signal::KILL), Ending::Killed),
    ];
    for (signal, label) in rungs {
        let running: Vec<bool> = children.iter_mut().map(|c| c.is_running()).collect();
        if !running.iter().any(|r| *r) {
            return;
        }
        match signal {
            None => send_shutdown(),
            Some(sig) => {
                for (c, r) in children.iter().zip(&running) {
                    if *r {
                        c.signal(sig);
                    }
                }
            }
        }
        wait_all(children, grace, while_waiting);
        for (c, r) in children.iter_mut().zip(&running) {
            if *r && !c.is_running() {
                c.ending = label.clone();
            }
        }
    }
}

/// Whether child `pid` has exited (checked without reaping it).
fn exited_unreaped(pid: u32) -> bool {
    use rustix::process::{waitid, Pid, WaitId, WaitIdOptions};
    let Some(pid) = Pid::from_raw(pid as i32) else {
        return false;
    };
    let opts = WaitIdOptions::EXITED | WaitIdOptions::NOHANG | WaitIdOptions::NOWAIT;
    matches!(waitid(WaitId::Pid(pid), opts), Ok(Some(_)))
}

/// User + system CPU time of process `pid` (`self` for this one) from `/proc/<pid>/stat` [s].
pub fn cpu_seconds(pid: impl std::fmt::Display) -> Option<f64> {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
    // Fields after the command name (which may hold spaces) in parentheses: utime is the 14th
    // field of the line, stime the 15th, in clock ticks.
    let rest = &stat[stat.rfind(')')? + 2..];
    let mut fields = rest.split_ascii_whitespace().skip(11);
    let utime: u64 = fields.next()?.parse().ok()?;
    let stime: u64 = fields.next()?.parse().ok()?;
    let hz = rustix::param::clock_ticks_per_second() as f64;
    Some((utime + stime) as f64 / hz)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The stop ladder on real processes and signals: one that ends within the grace after
    /// `Shutdown` is labelled `shutdown`, one that ignores it ends on SIGTERM (`sigterm`), one
    /// that ignores SIGTERM too ends on SIGKILL (`sigkill`). The `Shutdown` rung is the
    /// orchestrator's control message; here the stand-ins ignore it, as a hung service would.
    #[test]
    fn the_stop_ladder_climbs_from_shutdown_to_sigterm_to_sigkill() {
        let dir = std::env::temp_dir().join(format!("glint-ladder-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let exe = dir.join("stand-in.sh");
        // Called as `stand-in.sh service <name> --prefix … --scenario …`.
        std::fs::write(
            &exe,
            "#!/bin/sh\ncase \"$2\" in\n  sensor) exec sleep 0.3 ;;\n  detector) exec sleep 30 ;;\n  \
             *) trap '' TERM; exec sleep 30 ;;\nesac\n",
        )
        .unwrap();
        std::fs::set_permissions(&exe, std::os::unix::fs::PermissionsExt::from_mode(0o755))
            .unwrap();
        let spawn = |id| ServiceProcess::spawn(&exe, id, "p", &exe, &dir, 0, None).unwrap();
        let mut children = [
            spawn(ServiceId::Sensor),
            spawn(ServiceId::Detector),
            spawn(ServiceId::Tracker),
        ];
        let mut shutdowns = 0;
        stop_ladder(
            &mut children,
            Duration::from_millis(1000),
            &mut || shutdowns += 1,
            &mut || {},
        );
        assert_eq!(shutdowns, 1);
        let endings: Vec<String> = children.iter().map(|c| c.ending.label()).collect();
        assert_eq!(endings, ["shutdown", "sigterm", "sigkill"]);
        assert!(children.iter_mut().all(|c| c.poll_exit()));
        let _ = std::fs::remove_dir_all(&dir);
    }
}
