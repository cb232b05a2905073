//! Process helpers for the system tests that signal a deployment: find its services in /proc,
//! wait for process states and exits against deadlines, never leave a child behind.

use std::path::Path;
use std::process::{Child, ExitStatus, Stdio};
use std::time::{Duration, Instant};

use rustix::process::Pid;

use super::glint;

/// A child killed (SIGKILL) and reaped if the test ends first.
pub struct KillOnDrop(pub Child);

impl Drop for KillOnDrop {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// The fields of `PROC_DIR/stat` after the parenthesised command name: state, ppid, …
pub fn stat_fields(proc_dir: &str) -> Option<Vec<String>> {
    let stat = std::fs::read_to_string(format!("{proc_dir}/stat")).ok()?;
    let (_, rest) = stat.rsplit_once(')')?;
    Some(rest.split_whitespace().map(str::to_string).collect())
}

/// The process state letter of `pid` (`R`, `S`, `T`, `Z`, …), `None` once it is gone.
pub fn process_state(pid: u32) -> Option<char> {
    stat_fields(&format!("/proc/{pid}")).and_then(|f| f.first().and_then(|s| s.chars().next()))
}

/// Waits (at most 5 s) until the process state in `/proc/PID/stat` satisfies `ok`.
pub fn wait_for_state(pid: u32, ok: impl Fn(char) -> bool) {
    let t0 = Instant::now();
    loop {
        let state = process_state(pid);
        if state.is_some_and(&ok) {
            return;
        }
        assert!(
            t0.elapsed() < Duration::from_secs(5),
            "process {pid} state {state:?}"
        );
        std::thread::sleep(Duration::from_millis(2));
    }
}

/// The processes whose command line is `glint service <name> …` (any parent when `parent` is
/// `None`).
pub fn service_pids(parent: Option<u32>, name: &str) -> Vec<i32> {
    let mut out = vec![];
    let Ok(rd) = std::fs::read_dir("/proc") else {
        return out;
    };
    for entry in rd.flatten() {
        let Ok(pid) = entry.file_name().to_string_lossy().parse::<i32>() else {
            continue;
        };
        let cmdline = std::fs::read(entry.path().join("cmdline")).unwrap_or_default();
        let args: Vec<&[u8]> = cmdline.split(|&b| b == 0).collect();
        let is_service = args.len() > 2 && args[1] == b"service" && args[2] == name.as_bytes();
        if !is_service {
            continue;
        }
        let ppid = stat_fields(&entry.path().to_string_lossy())
            .and_then(|f| f.get(1).and_then(|p| p.parse::<u32>().ok()));
        if parent.is_none() || ppid == parent {
            out.push(pid);
        }
    }
    out
}

/// `glint run FILE --out OUT EXTRA…`, killed if the test ends first; its stderr goes to
/// [`stderr_path`]`(OUT)`.
pub fn start_run(file: &Path, out: &Path, extra: &[&str]) -> KillOnDrop {
    let stderr = std::fs::File::create(stderr_path(out)).expect("stderr file");
    KillOnDrop(
        glint()
            .arg("run")
            .arg(file)
            .arg("--out")
            .arg(out)
            .args(extra)
            .stdout(Stdio::null())
            .stderr(stderr)
            .spawn()
            .expect("spawn glint"),
    )
}

/// Where [`start_run`] writes the orchestrator's stderr: beside the run directory.
pub fn stderr_path(out: &Path) -> std::path::PathBuf {
    out.with_extension("stderr")
}

/// Waits (at most 60 s) until the orchestrator of the run in `out` has started the services.
pub fn wait_for_start(out: &Path) {
    let t0 = Instant::now();
    let log = stderr_path(out);
    while !std::fs::read_to_string(&log).is_ok_and(|l| l.contains("all services ready; started")) {
        assert!(
            t0.elapsed() < Duration::from_secs(60),
            "the run never started: {}",
            std::fs::read_to_string(&log).unwrap_or_default()
        );
        std::thread::sleep(Duration::from_millis(5));
    }
}

/// The pid of the run's service `name` once it exists (polled every `poll`, at most 60 s).
pub fn wait_for_service(run: &KillOnDrop, name: &str, poll: Duration) -> Pid {
    let t0 = Instant::now();
    loop {
        if let Some(pid) = service_pids(Some(run.0.id()), name).first() {
            return Pid::from_raw(*pid).expect("pid");
        }
        assert!(t0.elapsed() < Duration::from_secs(60), "no {name} started");
        std::thread::sleep(poll);
    }
}

/// The run's exit status (at most `limit`).
pub fn wait_for_exit(run: &mut KillOnDrop, limit: Duration) -> ExitStatus {
    let t0 = Instant::now();
    loop {
        if let Some(s) = run.0.try_wait().expect("wait") {
            return s;
        }
        assert!(t0.elapsed() < limit, "the run did not end within {limit:?}");
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// The `--prefix` argument on the command line of process `pid` (a `glint service`).
pub fn prefix_of(pid: Pid) -> String {
    let cmdline = std::fs::read(format!("/proc/{}/cmdline", pid.as_raw_nonzero()))
        .expect("the service's command line");
    let args: Vec<String> = cmdline
        .split(|&b| b == 0)
        .map(|a| String::from_utf8_lossy(a).into_owned())
        .collect();
    let at = args.iter().position(|a| a == "--prefix").expect("--prefix");
    args[at + 1].clone()
}
