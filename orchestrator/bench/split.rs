//! `glint bench pipeline --split`: the same chain split `sensor | detector + tracker` across
//! two `glint run --host` processes over loopback (a bridge on each side, Zenoh between), beside
//! the local deployment of the same bench, and the link's own limit in the same run: the same
//! frames over one plain TCP stream on loopback, no bridge, no shared memory.

use std::io::{Read, Write};
use std::path::Path;
use std::time::Instant;

use anyhow::{bail, Context, Result};
use serde_json::{json, Value};
use shared_types::scenario::{HostSpec, ServicePlacement};
use shared_types::{FrameHeader, Scenario};

use super::pipeline::{self, Deployed};

/// The ground host's part, ended with the bench whatever happens to the board's.
struct KillOnDrop(std::process::Child);

impl Drop for KillOnDrop {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// What the split deployment measured.
pub struct Split {
    pub deployed: Deployed,
    /// Frames the orchestrator's host's bridge put on the wire.
    pub frames_on_wire: u64,
    /// Bytes of those frames on the wire (header, pixels, envelope).
    pub frame_bytes_on_wire: u64,
    /// Lost on the link, refused off it (every topic, this host's bridge).
    pub link_lost: u64,
    pub refused: u64,
    /// The same frames over one plain TCP stream on loopback [frames/s].
    pub tcp_fps: f64,
}

fn free_port() -> Result<u16> {
    let l = std::net::TcpListener::bind("127.0.0.1:0").context("a free port on loopback")?;
    Ok(l.local_addr()?.port())
}

/// `sc` split: the sensor and the orchestrator on `board`, the detector and tracker on
/// `ground`, both on loopback.
fn split_scenario(sc: &Scenario) -> Result<Scenario> {
    let mut s = sc.clone();
    for (name, orchestrator) in [("board", true), ("ground", false)] {
        let endpoint = format!("tcp/127.0.0.1:{}", free_port()?);
        (s.hosts).insert(
            name.into(),
            HostSpec {
                endpoint,
                orchestrator,
            },
        );
    }
    for name in ["detector", "tracker"] {
        let p: &mut ServicePlacement = s.services.entry(name.into()).or_default();
        p.host = Some("ground".into());
    }
    if let Err(errs) = s.validate() {
        let all: Vec<String> = errs.iter().map(|e| e.to_string()).collect();
        bail!("the split scenario: {}", all.join("; "));
    }
    Ok(s)
}

/// Deploys `sc` split across two hosts on this machine into `out/split-board` and
/// `out/split-ground`, then streams the same frames over plain TCP.
pub fn measure(sc: &Scenario, out: &Path, progress: bool) -> Result<Split> {
    let split = split_scenario(sc)?;
    std::fs::create_dir_all(out)?;
    let file = out.join("split.toml");
    std::fs::write(&file, split.to_toml())?;
    // Both hosts read the same file, so they derive the same deployment key.
    let split = Scenario::from_file(&file).map_err(|e| anyhow::anyhow!("{e}"))?;
    let exe = std::env::current_exe()?;
    let ground_dir = out.join("split-ground");
    let ground_log = std::fs::File::create(out.join("split-ground.stderr"))?;
    let mut ground = KillOnDrop(
        std::process::Command::new(exe)
            .arg("run")
            .arg(&file)
            .args(["--host", "ground", "--force", "--out"])
            .arg(&ground_dir)
            .stdout(std::process::Stdio::null())
            .stderr(ground_log)
            .spawn()
            .context("starting the ground host's part")?,
    );
    let opts = crate::run::RunOptions {
        scenario: split.clone(),
        scenario_file: file.display().to_string(),
        out_dir: Some(out.join("split-board")),
        replace: true,
        progress,
        record: false,
        host: Some("board".into()),
    };
    let board = crate::run::run(opts);
    let ground_ok = ground.0.wait().is_ok_and(|s| s.success());
    let (dir, ok) = board?;
    let report: Value = serde_json::from_str(
        &std::fs::read_to_string(dir.join("report.json")).context("the split run's report")?,
    )?;
    if !ok || !ground_ok {
        bail!(
            "the split deployment failed: {} (see {} and {})",
            report["failure"]
                .as_str()
                .unwrap_or("the ground host's part"),
            dir.join("summary.md").display(),
            ground_dir.join("summary.md").display()
        );
    }
    let deployed = pipeline::read_report(&report);
    let hops: Vec<&Value> = (report["run"]["hosts"].as_array().into_iter().flatten())
        .flat_map(|h| h["hops"].as_array().into_iter().flatten())
        .collect();
    let sum = |field: &str| hops.iter().filter_map(|h| h[field].as_u64()).sum::<u64>();
    let frames_on_wire = (hops.iter())
        .find(|h| h["topic"] == "frame")
        .and_then(|h| h["passed_on"].as_u64())
        .unwrap_or(0);
    let frame_bytes = frame_bytes(sc);
    Ok(Split {
        deployed,
        frames_on_wire,
        frame_bytes_on_wire: frames_on_wire * (frame_bytes + ENVELOPE_BYTES),
        link_lost: sum("link_lost"),
        refused: sum("refused"),
        tcp_fps: tcp_limit(
            frame_bytes as usize,
            sc.camera.as_ref().map_or(0, |c| c.frames),
        )?,
    })
}

/// Bytes of one frame message: its header and its pixels.
fn frame_bytes(sc: &Scenario) -> u64 {
    (std::mem::size_of::<FrameHeader>() + 2 * sc.frame_px()) as u64
}

/// The envelope beside each message on the wire (ADR 0038).
#[cfg(feature = "hosts")]
const ENVELOPE_BYTES: u64 = glint_bridge::envelope::ENVELOPE_BYTES as u64;
/// Without the bridge nothing is split (`--split` is refused).
#[cfg(not(feature = "hosts"))]
const ENVELOPE_BYTES: u64 = 0;

/// `frames` messages of `bytes` each through one TCP stream on loopback, written and read in
/// full, each from a buffer of its own (as the bridge takes each frame out of shared memory):
/// the link's limit [frames/s].
fn tcp_limit(bytes: usize, frames: u64) -> Result<f64> {
    let listener = std::net::TcpListener::bind("127.0.0.1:0")?;
    let addr = listener.local_addr()?;
    let reader = std::thread::spawn(move || -> std::io::Result<u64> {
        let (mut s, _) = listener.accept()?;
        let mut buf = vec![0u8; bytes];
        let mut n = 0;
        while n < frames {
            s.read_exact(&mut buf)?;
            n += 1;
        }
        Ok(n)
    });
    let mut s = std::net::TcpStream::connect(addr)?;
    let frame: Vec<u8> = (0..bytes).map(|i| i as u8).collect();
    let t0 = Instant::now();
    for _ in 0..frames {
        let copy = frame.clone();
        s.write_all(&copy)?;
    }
    s.flush()?;
    let n = reader
        .join()
        .map_err(|_| anyhow::anyhow!("the TCP reader panicked"))??;
    Ok(n as f64 / t0.elapsed().as_secs_f64())
}

/// Prints the split's lines and gives its part of bench.json.
pub fn report(s: &Split, local: &Deployed) -> Value {
    let ratio = s.deployed.fps / local.fps;
    println!(
        "split across two hosts (loopback, a bridge each side): {:.1} frames/s, {ratio:.2}× the \
         local deployment's {:.1}; the link alone (one TCP stream, the same frames): {:.1} \
         frames/s",
        s.deployed.fps, local.fps, s.tcp_fps
    );
    let mib = s.frame_bytes_on_wire as f64 / (1u64 << 20) as f64;
    let secs = s.frames_on_wire as f64 / s.deployed.fps.max(1e-9);
    println!(
        "  on the wire: {} frames, {mib:.0} MiB ({:.0} MiB/s); lost on the link {}, refused {}; \
         dropped {}; science {} the local run's",
        s.frames_on_wire,
        mib / secs.max(1e-9),
        s.link_lost,
        s.refused,
        s.deployed.dropped,
        if s.deployed.science_digest == local.science_digest {
            "equal to"
        } else {
            "DIFFERENT from"
        }
    );
    for (name, p50, p99) in &s.deployed.stages {
        let here = (local.stages.iter()).find(|(n, _, _)| n == name);
        let local_p50 = here.map_or("—".into(), |(_, p, _)| format!("{p:.0}"));
        println!("  {name}: p50 {p50:.0} µs (local {local_p50} µs), p99 {p99:.0} µs");
    }
    json!({
        "frames_per_s": s.deployed.fps,
        "frames_per_s_local": local.fps,
        "ratio": ratio,
        "tcp_frames_per_s": s.tcp_fps,
        "frames_on_wire": s.frames_on_wire,
        "frame_bytes_on_wire": s.frame_bytes_on_wire,
        "link_lost": s.link_lost,
        "refused": s.refused,
        "dropped": s.deployed.dropped,
        "science_equal": s.deployed.science_digest == local.science_digest,
        "stages_us": (s.deployed.stages.iter())
            .map(|(n, p50, p99)| (n.clone(), json!({"p50": p50, "p99": p99})))
            .collect::<serde_json::Map<_, _>>(),
    })
}
