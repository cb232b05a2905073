//! The Python client (`python/`, package `glint_client` on iceoryx2 0.10.0 from PyPI): its own
//! tests, run against this build's `glint` — a live deployment's frames received as read-only
//! numpy views inside the deployment's shared memory, each frame's pixel checksum and the
//! frame and detections digests equal to the report's; a recording read with the `mcap` PyPI
//! package, every channel's count equal to the report's `published`.
//!
//! The environment is `python/.venv` (the README's test command, `./test`, makes it) or the
//! interpreter `GLINT_PYTHON` names.

mod common;

use std::path::PathBuf;
use std::process::Command;

use common::python;

#[test]
fn the_python_client_reads_live_frames_without_copying_and_reads_recordings() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let out = Command::new(python())
        .args(["-m", "pytest", "-q", "-p", "no:cacheprovider", "tests"])
        .current_dir(root.join("python"))
        .env("GLINT_BIN", env!("CARGO_BIN_EXE_glint"))
        .output()
        .expect("running pytest");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "pytest failed:\n{stdout}\n{stderr}");
    // every test ran: none skipped for want of a binary or a package
    let last = stdout
        .lines()
        .rev()
        .find(|l| l.contains("passed"))
        .unwrap_or("");
    assert!(
        !last.contains("skipped") && !last.contains("deselected"),
        "{last}"
    );
    let passed: u32 = (last.split_whitespace())
        .zip(last.split_whitespace().skip(1))
        .find(|(_, w)| w.starts_with("passed"))
        .and_then(|(n, _)| n.parse().ok())
        .unwrap_or(0);
    assert!(passed >= 10, "{stdout}");
}
