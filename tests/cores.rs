//! The services' cores driven in-process, without shared memory or processes: the sensor's
//! core renders frames into a plain buffer, the detector's core reads them, the tracker's core
//! takes its detections and fires its laser at the sensor's core directly. Deployed as
//! processes over iceoryx2, the same scenario must give byte-identical detections and tracks —
//! the report's topic digests are the independent reference — so the skeleton adds transport,
//! credit, acks and supervision, and changes no result.

mod common;

use glint_detector::service_core::DetectorCore;
use glint_sensor::service_core::SensorCore;
use glint_sensor::streams::{FrameStream, Stream};
use glint_tracker::service_core::{Laser, TrackerCore};
use shared_types::{
    FrameHeader, Message, Meta, RangeRequest, RangeResponse, Scenario, ServiceId, Truth,
};
use xxhash_rust::xxh3::Xxh3;

/// The sensor's laser, called in-process with the request ids the tracker's client would give.
struct DirectLaser<'a> {
    sensor: &'a SensorCore,
    next_id: u64,
    shots: u64,
}

impl Laser for DirectLaser<'_> {
    fn fire(&mut self, mut req: RangeRequest, t_ns: u64) -> anyhow::Result<Option<RangeResponse>> {
        req.request_id = self.next_id;
        req.meta = Meta::new(self.next_id, t_ns, 0, ServiceId::Tracker);
        self.next_id += 1;
        self.shots += 1;
        let (mut resp, echo_ns) = self.sensor.answer_range(&req);
        resp.meta = Meta::new(0, echo_ns, 0, ServiceId::Sensor);
        Ok(Some(resp))
    }
}

/// A message as the wire carries it (seq, time, producer, sealed), folded into a topic digest
/// the way the orchestrator does (`Message::fold_digest`).
fn fold<T: Message>(digest: &mut Xxh3, mut msg: T, seq: u64, t_ns: u64, producer: ServiceId) {
    *msg.meta_mut() = Meta::new(seq, t_ns, 0, producer);
    msg.seal();
    msg.fold_digest(digest);
}

struct Chain {
    detections_digest: u64,
    tracks_digest: u64,
    frames: u64,
    detections: u64,
    shots: u64,
    truths: Vec<Truth>,
    /// Per frame: (frame index, the detections' end points [px]).
    end_points: Vec<(u64, Vec<[f64; 2]>)>,
}

fn run_in_process(scenario: &Scenario) -> Chain {
    let cam = scenario.camera.as_ref().expect("a [camera] scenario");
    let sensor = SensorCore::new(scenario).expect("sensor core");
    let mut detector = DetectorCore::new(cam).expect("detector core");
    let mut tracker = TrackerCore::new(cam).expect("tracker core");
    let mut laser = DirectLaser {
        sensor: &sensor,
        next_id: 0,
        shots: 0,
    };
    let (mut det_digest, mut trk_digest) = (Xxh3::new(), Xxh3::new());
    let mut chain = Chain {
        detections_digest: 0,
        tracks_digest: 0,
        frames: 0,
        detections: 0,
        shots: 0,
        truths: vec![],
        end_points: vec![],
    };
    let mut pixels = vec![0u16; cam.pixels()];
    // Frames only: the spectra of a combined scenario do not touch this chain.
    let frames = sensor.debris_stream().expect("a camera");
    for frame in 0..frames.messages() {
        let t_ns = frames.t_ns(frame);
        let mut header = FrameHeader {
            meta: Meta::new(frame, t_ns, 0, ServiceId::Sensor),
            ..Default::default()
        };
        frames.render(frame, &mut header, &mut pixels);
        chain.truths.push(frames.truth(frame));
        let d = detector
            .process(&header, &pixels)
            .expect("a readable frame");
        let items = &d.items[..d.n as usize];
        chain.end_points.push((
            frame,
            items.iter().map(|i| [i.end_x_px, i.end_y_px]).collect(),
        ));
        chain.detections += d.n as u64;
        let tracks = tracker.process(&d, &mut laser).expect("tracks");
        fold(&mut det_digest, d, frame, t_ns, ServiceId::Detector);
        fold(&mut trk_digest, tracks, frame, t_ns, ServiceId::Tracker);
        chain.frames += 1;
    }
    chain.detections_digest = det_digest.digest();
    chain.tracks_digest = trk_digest.digest();
    chain.shots = laser.shots;
    chain
}

fn digest_of(report: &glint::report::Report, topic: &str) -> u64 {
    let hex = (report.results.topics.get(topic))
        .and_then(|t| t.digest_xxh3.as_deref())
        .unwrap_or_else(|| panic!("no digest for {topic}"));
    u64::from_str_radix(hex, 16).expect("hex digest")
}

#[test]
fn cores_in_process_reproduce_the_deployment_byte_for_byte() {
    let path = common::scenario("debris-geo.toml");
    let scenario = Scenario::from_file(&path).expect("scenario");
    let chain = run_in_process(&scenario);
    let cam = scenario.camera.as_ref().unwrap();
    assert_eq!(chain.frames, cam.frames);
    assert!(
        chain.detections > chain.frames,
        "detections: {}",
        chain.detections
    );
    assert!(chain.shots > 0, "the laser was never fired");

    let dir = common::temp_dir("cores");
    let run = common::run_ok(Some(&path), &dir, &[]);
    let report = &run.typed;
    assert_eq!(
        digest_of(report, "detections"),
        chain.detections_digest,
        "detections differ between the in-process cores and the deployment"
    );
    assert_eq!(
        digest_of(report, "tracks"),
        chain.tracks_digest,
        "tracks differ between the in-process cores and the deployment"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// The detector's core against the sensor's own geometry: every streak the sensor rendered
/// fully inside the frame is found, its end point within 1.5 px of where the sensor put it.
#[test]
fn detector_core_finds_every_rendered_streak() {
    let scenario = Scenario::from_file(&common::scenario("debris-geo.toml")).expect("scenario");
    let cam = scenario.camera.as_ref().unwrap();
    let sensor = SensorCore::new(&scenario).expect("sensor core");
    let scene = sensor.debris.as_ref().expect("debris scene");
    let chain = run_in_process(&scenario);
    let (w, h) = (cam.width_px as f64, cam.height_px as f64);
    let mut checked = 0;
    // From the third frame on the matcher has two frames of each streak.
    for (frame, ends) in chain.end_points.iter().skip(2) {
        let streaks = scene.streaks(*frame);
        // The debris first, then the stationary false targets (the matcher rejects those).
        let n_debris = streaks.len() - scene.false_targets(*frame).len();
        for s in &streaks[..n_debris] {
            let inside = |x: f64, y: f64| x > 10.0 && y > 10.0 && x < w - 10.0 && y < h - 10.0;
            if !(inside(s.x0_px, s.y0_px) && inside(s.x1_px, s.y1_px)) || s.total_signal_dn < 1e3 {
                continue;
            }
            let best = ends
                .iter()
                .map(|e| (e[0] - s.x1_px).hypot(e[1] - s.y1_px))
                .fold(f64::INFINITY, f64::min);
            assert!(
                best < 1.5,
                "frame {frame}: streak ending at ({:.1}, {:.1}) px: nearest end point {best:.2} px",
                s.x1_px,
                s.y1_px
            );
            checked += 1;
        }
    }
    assert!(checked > 50, "only {checked} streaks checked");
    assert_eq!(chain.truths.len() as u64, chain.frames);
}
