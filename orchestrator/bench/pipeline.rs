//! `glint bench pipeline`: the [002] chain (sensor → detector → tracker, laser loop) deployed as
//! processes over iceoryx2, against the same work done sequentially in this process by the
//! same cores, in the same run.
//!
//! The deployment is an ordinary `glint run` (its run directory lands in `DIR/run`); its
//! report gives frames/s, drops, each process's CPU time and the per-stage latencies from the
//! messages' send times. The in-process baseline times each core call per frame: render,
//! checksum, detect, track (with the laser answered directly by the sensor's core).

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{bail, Context, Result};
use glint_detector::service_core::DetectorCore;
use glint_sensor::service_core::SensorCore;
use glint_sensor::streams::{FrameStream, Stream};
use glint_tracker::service_core::{Laser, TrackerCore};
use serde_json::{json, Value};
use shared_types::scenario::{Clock, Debris};
use shared_types::{FrameHeader, Meta, RangeRequest, RangeResponse, Scenario, ServiceId};

/// The scene the pipeline bench varies: [002]'s GEO debris (Table 4).
const BASE: &str = include_str!("../../scenarios/debris-geo.toml");

/// Options of `glint bench pipeline`.
pub struct PipelineOptions {
    pub out: PathBuf,
    pub frames: u64,
    pub width_px: u32,
    pub height_px: u32,
    pub targets: usize,
    pub clock: Clock,
    pub laser: bool,
}

/// The benchmark's scenario: debris-geo with the options applied. Debris beyond the paper's
/// four are copies of them shifted along-track, so every target stays in the field of view.
pub fn scenario(o: &PipelineOptions) -> Result<Scenario, String> {
    let mut sc = Scenario::from_toml_str(BASE, "debris-geo.toml").map_err(|e| e.to_string())?;
    sc.name = "bench-pipeline".into();
    sc.clock = o.clock;
    let cam = sc.camera.as_mut().ok_or("debris-geo has no camera")?;
    cam.frames = o.frames;
    cam.width_px = o.width_px;
    cam.height_px = o.height_px;
    cam.tracker.laser = o.laser;
    let table4 = cam.debris.clone();
    cam.debris = (0..o.targets)
        .map(|k| {
            let d = &table4[k % table4.len()];
            let shift_m = 250.0 * (k / table4.len()) as f64;
            Debris {
                x_m: d.x_m + shift_m,
                ..d.clone()
            }
        })
        .collect();
    // Long runs: the run's timeout grows with the work.
    sc.run.timeout_s = (60.0 + o.frames as f64 * 0.02).min(86_400.0);
    sc.validate().map_err(|errs| {
        errs.iter()
            .map(|e| e.to_string())
            .collect::<Vec<_>>()
            .join("; ")
    })?;
    Ok(sc)
}

/// The sensor's laser answered in-process, as the tracker's client would ask it.
struct DirectLaser<'a> {
    sensor: &'a SensorCore,
    next_id: u64,
    busy_ns: u64,
}

impl Laser for DirectLaser<'_> {
    fn fire(&mut self, mut req: RangeRequest, t_ns: u64) -> Result<Option<RangeResponse>> {
        let t0 = Instant::now();
        req.request_id = self.next_id;
        req.meta = Meta::new(self.next_id, t_ns, 0, ServiceId::Tracker);
        self.next_id += 1;
        let (mut resp, echo_ns) = self.sensor.answer_range(&req);
        resp.meta = Meta::new(0, echo_ns, 0, ServiceId::Sensor);
        self.busy_ns += t0.elapsed().as_nanos() as u64;
        Ok(Some(resp))
    }
}

/// Per-frame times of the in-process run [ns], one vector per stage.
pub struct InProcess {
    pub frames: u64,
    pub wall_s: f64,
    pub stages: Vec<(&'static str, Vec<u64>)>,
    /// Frame buffers it renders into in turn: as many as the deployment's frame samples in
    /// circulation (the topic's history and one loan).
    pub pool_frames: usize,
    /// The physical floor: one read pass over a frame [µs], hot (a frame just read: in the
    /// caches, L3 for a 2 MiB frame) and cold (from memory).
    pub pass_hot_us: f64,
    pub pass_cold_us: f64,
}

/// Reads every byte of `frame` once (a sum of its 64-bit words).
fn read_pass(frame: &[u16]) -> u64 {
    let words: &[u64] = bytemuck::cast_slice(&frame[..frame.len() / 4 * 4]);
    words.iter().fold(0u64, |a, w| a.wrapping_add(*w))
}

/// The median time [µs] of one read pass over a frame of `px` pixels: over the same frame
/// again and again (hot: in the caches, L3 for a 2 MiB frame), and over the frames of a
/// 256 MiB pool in turn, each written and then left untouched while 128 MiB more were written
/// (cold: from memory).
fn floor_us(px: usize) -> (f64, f64) {
    const POOL_BYTES: usize = 256 << 20;
    const PASSES: usize = 64;
    let median = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let time = |f: &[u16]| {
        let t0 = Instant::now();
        std::hint::black_box(read_pass(std::hint::black_box(f)));
        t0.elapsed().as_secs_f64() * 1e6
    };
    let hot = vec![1u16; px];
    read_pass(&hot);
    let hot_us = median((0..PASSES).map(|_| time(&hot)).collect());
    let n = (POOL_BYTES / (2 * px).max(1)).max(2);
    // every frame written (not the kernel's zero pages), distinct
    let pool: Vec<Vec<u16>> = (0..n).map(|k| vec![(k as u16) | 1; px]).collect();
    // the first half in order, each once: the second half's writes evicted them
    let cold_us = median(pool[..n / 2].iter().take(PASSES).map(|f| time(f)).collect());
    (hot_us, cold_us)
}

/// The chain's cores called one after the other on every frame of `sc`.
pub fn in_process(sc: &Scenario, bar: &indicatif::ProgressBar) -> Result<InProcess> {
    let cam = sc.camera.as_ref().context("a [camera] scenario")?;
    let sensor = SensorCore::new(sc)?;
    let frames = sensor.debris_stream().context("a [camera] scenario")?;
    let mut detector = DetectorCore::new(cam).map_err(|e| anyhow::anyhow!("{e}"))?;
    let mut tracker = TrackerCore::new(cam).map_err(|e| anyhow::anyhow!("{e}"))?;
    let mut laser = DirectLaser {
        sensor: &sensor,
        next_id: 0,
        busy_ns: 0,
    };
    // The same pool of frames as the deployment's samples, written in turn: a frame rendered
    // into a buffer last used that many frames ago, as the sensor's loan is.
    let pool_frames = shared_types::topics::frame_window(cam.pixels()) + 1;
    // written once here, so that no render pays the pages' first touch
    let mut pool: Vec<Vec<u16>> = (0..pool_frames).map(|_| vec![1u16; cam.pixels()]).collect();
    let (mut render, mut checksum, mut verify, mut detect, mut track, mut ranging) =
        (vec![], vec![], vec![], vec![], vec![], vec![]);
    let wall = Instant::now();
    for frame in 0..frames.messages() {
        let pixels = &mut pool[frame as usize % pool_frames];
        let t_ns = frames.t_ns(frame);
        let mut header = FrameHeader {
            meta: Meta::new(frame, t_ns, 0, ServiceId::Sensor),
            ..Default::default()
        };
        let t0 = Instant::now();
        frames.render(frame, &mut header, pixels);
        let t1 = Instant::now();
        header.pixels_xxh3 = shared_types::pixels_xxh3(pixels);
        let t2 = Instant::now();
        // the detector's check of what it received (its port verifies every frame)
        if shared_types::pixels_xxh3(pixels) != header.pixels_xxh3 {
            bail!("frame {frame}: its checksum does not hold in one process");
        }
        let t3 = Instant::now();
        let d = match detector.process(&header, pixels) {
            Ok(d) => d,
            Err(reason) => bail!("frame {frame} rejected by the detector: {reason:?}"),
        };
        let t4 = Instant::now();
        let before = laser.busy_ns;
        std::hint::black_box(tracker.process(&d, &mut laser)?);
        let t5 = Instant::now();
        let laser_ns = laser.busy_ns - before;
        render.push((t1 - t0).as_nanos() as u64);
        checksum.push((t2 - t1).as_nanos() as u64);
        verify.push((t3 - t2).as_nanos() as u64);
        detect.push((t4 - t3).as_nanos() as u64);
        track.push(((t5 - t4).as_nanos() as u64).saturating_sub(laser_ns));
        ranging.push(laser_ns);
        bar.inc(1);
    }
    let wall_s = wall.elapsed().as_secs_f64();
    drop(pool);
    let (pass_hot_us, pass_cold_us) = floor_us(cam.pixels());
    Ok(InProcess {
        frames: frames.messages(),
        wall_s,
        stages: vec![
            ("render", render),
            ("checksum", checksum),
            ("verify", verify),
            ("detect", detect),
            ("track", track),
            ("laser", ranging),
        ],
        pool_frames,
        pass_hot_us,
        pass_cold_us,
    })
}

/// (mean, p50, p99) [µs] of per-frame times in ns.
pub fn stats_us(ns: &[u64]) -> (f64, f64, f64) {
    if ns.is_empty() {
        return (f64::NAN, f64::NAN, f64::NAN);
    }
    let mut v = ns.to_vec();
    v.sort_unstable();
    let p = |q: f64| v[((v.len() - 1) as f64 * q).round() as usize] as f64 / 1e3;
    let mean = v.iter().sum::<u64>() as f64 / v.len() as f64 / 1e3;
    (mean, p(0.5), p(0.99))
}

/// What the deployment's report says, as the bench needs it.
pub struct Deployed {
    pub frames: u64,
    pub fps: f64,
    pub dropped: u64,
    /// Per process: (name, CPU [s]).
    pub cpu_s: Vec<(String, f64)>,
    /// Per stage: (name, p50 [µs], p99 [µs]) from the messages' send times.
    pub stages: Vec<(String, f64, f64)>,
    /// Per process: where its time went (the report's `timing.time_s`).
    pub time_s: serde_json::Map<String, Value>,
    pub science_digest: String,
    pub success: bool,
}

pub fn read_report(report: &Value) -> Deployed {
    let timing = &report["timing"];
    let cpu_s: Vec<(String, f64)> = (timing["cpu_s"].as_object().into_iter().flatten())
        .filter_map(|(name, c)| Some((name.clone(), c.as_f64()?)))
        .collect();
    let mut stages = vec![];
    let lat = |v: &Value| (v["p50"].as_f64(), v["p99"].as_f64());
    if let (Some(a), Some(b)) = lat(&timing["frame_latency_us"]) {
        stages.push(("frame_hop".to_string(), a, b));
    }
    if let Some(m) = timing["stage_latency_us"].as_object() {
        for name in ["detect", "track", "end_to_end"] {
            if let Some((Some(a), Some(b))) = m.get(name).map(lat) {
                stages.push((name.to_string(), a, b));
            }
        }
    }
    let dropped = (report["topics"].as_object().into_iter().flatten())
        .flat_map(|(_, t)| t["consumers"].as_object().into_iter().flatten())
        .map(|(_, c)| c["dropped"].as_u64().unwrap_or(0))
        .sum();
    Deployed {
        frames: report["topics"]["frame"]["published"].as_u64().unwrap_or(0),
        fps: timing["frames_per_s"].as_f64().unwrap_or(0.0),
        dropped,
        cpu_s,
        stages,
        time_s: timing["time_s"].as_object().cloned().unwrap_or_default(),
        science_digest: report["science"]["digest_xxh3"]
            .as_str()
            .unwrap_or("")
            .into(),
        success: report["success"].as_bool().unwrap_or(false),
    }
}

/// The `pipeline` section of bench.json.
pub fn json(o: &PipelineOptions, d: &Deployed, ip: &InProcess) -> Value {
    let in_fps = ip.frames as f64 / ip.wall_s.max(1e-9);
    let cpu = |name: &str| d.cpu_s.iter().find(|(n, _)| n == name).map(|(_, c)| *c);
    let lat = |name: &str| d.stages.iter().find(|(n, ..)| n == name);
    let stage = |name: &str, process: &str| {
        let l = lat(name);
        json!({
            "p50_us": l.map(|s| s.1), "p99_us": l.map(|s| s.2),
            "cpu_s": cpu(process), "process": process,
        })
    };
    let (_, r50, r99) = stats_us(&ip.stages[0].1);
    let breakdown: serde_json::Map<String, Value> = (ip.stages.iter())
        .map(|(name, ns)| {
            let (mean, p50, p99) = stats_us(ns);
            (
                name.to_string(),
                json!({ "mean_us": mean, "p50_us": p50, "p99_us": p99 }),
            )
        })
        .collect();
    json!({
        "method": "frames/s = frames / the deployment's production time (Start to the last result \
                   accounted for); stage latencies from the messages' CLOCK_MONOTONIC send times \
                   (sensor: its render in the in-process run; detector: frame sent → detections \
                   sent; tracker: detections sent → tracks sent; orchestrator: frame sent → \
                   received); cpu_s = user + system time of each process (/proc); in_process = \
                   the same cores called sequentially in one process on the same frames, \
                   rendered into a pool of as many frames as the deployment circulates, \
                   checksummed and verified as the ports do; floor = one read pass over a \
                   frame hot (in the caches) and cold (from memory), in the same run",
        "scenario": {
            "frames": o.frames, "width_px": o.width_px, "height_px": o.height_px,
            "targets": o.targets, "clock": format!("{:?}", o.clock).to_lowercase(),
            "laser": o.laser,
        },
        "frames": d.frames,
        "fps": d.fps,
        "in_process_fps": in_fps,
        "speedup": d.fps / in_fps.max(1e-9),
        "dropped": d.dropped,
        "success": d.success,
        "science_digest": d.science_digest,
        "stages": {
            "sensor": { "p50_us": r50, "p99_us": r99, "cpu_s": cpu("sensor"), "process": "sensor" },
            "detector": stage("detect", "detector"),
            "tracker": stage("track", "tracker"),
            "orchestrator": stage("frame_hop", "orchestrator"),
            "end_to_end": stage("end_to_end", "all"),
        },
        "time_s": d.time_s,
        "in_process": {
            "frames": ip.frames, "wall_s": ip.wall_s, "stages": breakdown,
            "pool_frames": ip.pool_frames,
        },
        "floor": { "pass_hot_us": ip.pass_hot_us, "pass_cold_us": ip.pass_cold_us },
    })
}

/// The terminal table: the answer first, then where the time goes.
pub fn print(o: &PipelineOptions, d: &Deployed, ip: &InProcess) {
    let in_fps = ip.frames as f64 / ip.wall_s.max(1e-9);
    println!(
        "pipeline: {:.0} frames/s as processes, {:.0} frames/s in one process: {:.2}×; \
         {} dropped; {} frames of {}×{}, {} debris, laser {}, {} clock",
        d.fps,
        in_fps,
        d.fps / in_fps.max(1e-9),
        d.dropped,
        d.frames,
        o.width_px,
        o.height_px,
        o.targets,
        if o.laser { "on" } else { "off" },
        format!("{:?}", o.clock).to_lowercase()
    );
    println!("\nper process (the deployment)\n");
    println!(
        "{:<13} {:>9} {:>15}",
        "process", "CPU [s]", "CPU/frame [ms]"
    );
    for (name, c) in &d.cpu_s {
        println!(
            "{:<13} {:>9.2} {:>15.3}",
            name,
            c,
            c * 1e3 / d.frames.max(1) as f64
        );
    }
    println!("\nlatency per stage (the deployment, from the messages' send times)\n");
    println!("{:<13} {:>10} {:>10}", "stage", "p50 [µs]", "p99 [µs]");
    for (name, p50, p99) in &d.stages {
        println!("{name:<13} {p50:>10.1} {p99:>10.1}");
    }
    print_time(d);
    println!("\nwhere the time goes (in one process, per frame)\n");
    println!(
        "{:<13} {:>10} {:>10} {:>10}",
        "core", "mean [µs]", "p50 [µs]", "p99 [µs]"
    );
    for (name, ns) in &ip.stages {
        let (mean, p50, p99) = stats_us(ns);
        println!("{name:<13} {mean:>10.1} {p50:>10.1} {p99:>10.1}");
    }
    println!(
        "\n(one process: {} frame buffers in turn, as the deployment's samples; the floor, one \
         read pass over a frame: {:.1} µs hot, {:.1} µs cold from memory)",
        ip.pool_frames, ip.pass_hot_us, ip.pass_cold_us
    );
}

/// The parts of a process's time in the deployment (heading, the report's `time_s` key): busy
/// (its work, checksums, publishing, laser round trips) or asleep (held back by a consumer's
/// credit, or idle).
const TIME_PARTS: [(&str, &str); 6] = [
    ("work", "work_s"),
    ("checksum", "checksum_s"),
    ("publish", "publish_s"),
    ("laser wait", "rpc_wait_s"),
    ("credit wait", "credit_wait_s"),
    ("idle", "idle_s"),
];

/// `DIR/pipeline-time.svg`: each process's time per frame in the deployment, part by part.
pub fn plot_time(dir: &std::path::Path, d: &Deployed) -> Result<()> {
    use crate::plots::{self, Bar};
    let colors = [
        plots::BLUE,
        plots::GREEN,
        plots::ORANGE,
        plots::PURPLE,
        plots::RED,
        plots::GREY,
    ];
    let parts: Vec<(&str, _)> = TIME_PARTS.iter().map(|p| p.0).zip(colors).collect();
    let per_frame_ms = 1e3 / d.frames.max(1) as f64;
    let bars: Vec<Bar> = (d.time_s.iter())
        .map(|(name, t)| Bar {
            name,
            lengths: (TIME_PARTS.iter())
                .map(|(_, key)| t[key].as_f64().unwrap_or(f64::NAN) * per_frame_ms)
                .collect(),
        })
        .collect();
    plots::stacked_bars(
        &dir.join("pipeline-time.svg"),
        "Where each process's time goes (the deployment)",
        "ms per frame",
        &parts,
        &bars,
    )
}

/// Each process's time per frame in the deployment, part by part ([`TIME_PARTS`]).
fn print_time(d: &Deployed) {
    const COLUMNS: [(&str, &str); 6] = TIME_PARTS;
    println!("\nwhere the time goes (the deployment, ms per frame)\n");
    print!("{:<13}", "process");
    for (head, _) in COLUMNS {
        print!(" {head:>11}");
    }
    println!();
    let per_frame_ms = 1e3 / d.frames.max(1) as f64;
    for (name, t) in &d.time_s {
        print!("{name:<13}");
        for (_, key) in COLUMNS {
            print!(
                " {:>11.3}",
                t[key].as_f64().unwrap_or(f64::NAN) * per_frame_ms
            );
        }
        println!();
    }
}
