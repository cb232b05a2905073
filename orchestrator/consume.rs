//! The orchestrator as a consumer: it reads `truth` (for scoring), the heartbeats of every
//! service, and — until consumer services exist for them — the frames and spectra themselves,
//! verifying each one and folding it into a digest so two runs can be compared byte for byte.

use std::collections::BTreeMap;
use std::time::Instant;

use anyhow::Result;
use glint_runtime::ports::{FrameInbox, Inbox, Outbox};
use glint_runtime::TopicStats;
use iceoryx2::port::listener::Listener;
use shared_types::scenario::FaultKind;
use shared_types::topics::{
    ack_service, control_service, detections_service, earth_attitude_service, earth_frame_service,
    frame_service, heartbeat_service, spectrum_service, tracks_service, truth_service, Ipc,
    IpcNode,
};
use shared_types::{
    deployment, Ack, Command, Control, Detections, DropReason, EarthAttitude, Heartbeat,
    InBandFault, Replay, Scenario, ServiceId, Spectrum, TopicCounters, TopicId, Tracks, Truth,
};
use xxhash_rust::xxh3::Xxh3;

/// The last heartbeat of a service and when it arrived.
pub struct Seen {
    pub heartbeat: Heartbeat,
    pub at: Instant,
}

pub struct Consumer {
    pub frames: Option<FrameInbox>,
    pub spectra: Option<Inbox<Spectrum>>,
    pub truth: Inbox<Truth>,
    pub detections: Option<Inbox<Detections>>,
    pub tracks: Option<Inbox<Tracks>>,
    pub earth_frames: Option<FrameInbox>,
    pub earth: Option<Inbox<EarthAttitude>>,
    heartbeats: Inbox<Heartbeat>,
    control: Outbox<Control>,
    acks: Outbox<Ack>,
    frame_digest: Xxh3,
    spectrum_digest: Xxh3,
    truth_digest: Xxh3,
    /// Send → receive latency of every frame [ns].
    pub frame_latency_ns: Vec<u64>,
    /// Per frame received: (seq, the sensor's send time [ns, CLOCK_MONOTONIC]).
    pub frame_send_ns: Vec<(u64, u64)>,
    /// Send → receive latency of every spectrum [ns].
    pub spectrum_latency_ns: Vec<u64>,
    pub truths: Vec<Truth>,
    pub detection_msgs: Vec<Detections>,
    pub track_msgs: Vec<Tracks>,
    /// Pixels of one frame kept for the annotated picture (frame index, width, height, pixels).
    pub snapshot: Option<(u64, u32, u32, Vec<u16>)>,
    snapshot_frame: u64,
    detections_digest: Xxh3,
    tracks_digest: Xxh3,
    earth_frame_digest: Xxh3,
    earth_digest: Xxh3,
    pub earth_msgs: Vec<EarthAttitude>,
    /// Pixels of one Earth frame for the annotated picture (frame index, width, height, pixels).
    pub earth_snapshot: Option<(u64, u32, u32, Vec<u16>)>,
    earth_snapshot_frame: u64,
    /// Received spectra, reduced for the light-curve plot: (stream index, band centres, flux).
    pub light_curve: Vec<(u64, [f64; 3], [f64; 3])>,
    /// Every received spectrum (exported as `observations.csv`).
    pub spectra_msgs: Vec<Spectrum>,
    pub seen: BTreeMap<ServiceId, Seen>,
    /// Messages on each consumed topic the run must account for.
    pub expected: BTreeMap<TopicId, u64>,
    acked: BTreeMap<TopicId, u64>,
}

/// Listeners to attach to the orchestrator's WaitSet, in this order: heartbeat, truth, frame?,
/// spectrum?.
pub struct Listeners {
    pub heartbeat: Listener<Ipc>,
    pub truth: Listener<Ipc>,
    pub frame: Option<Listener<Ipc>>,
    pub spectrum: Option<Listener<Ipc>>,
    pub detections: Option<Listener<Ipc>>,
    pub tracks: Option<Listener<Ipc>>,
    pub earth_frame: Option<Listener<Ipc>>,
    pub earth: Option<Listener<Ipc>>,
}

impl Consumer {
    pub fn open(node: &IpcNode, scenario: &Scenario) -> Result<(Self, Listeners)> {
        let me = ServiceId::Orchestrator;
        let consumes = |t| deployment::consumers(scenario, t).contains(&me);
        let (frames, frame_l) = if consumes(TopicId::Frame) {
            let (mut i, l) = FrameInbox::open(node, &frame_service(node, scenario.frame_px())?)?;
            // When the detector reads the pixels, the orchestrator reads headers only (accounting
            // and the digest); the detector verifies the pixel checksum.
            i.verify_checksum =
                !deployment::consumers(scenario, TopicId::Frame).contains(&ServiceId::Detector);
            (Some(i), Some(l))
        } else {
            (None, None)
        };
        let (spectra, spectrum_l) = if consumes(TopicId::Spectrum) {
            let (i, l) = Inbox::open(node, TopicId::Spectrum, &spectrum_service(node)?)?;
            (Some(i), Some(l))
        } else {
            (None, None)
        };
        let (truth, truth_l) = Inbox::open(node, TopicId::Truth, &truth_service(node)?)?;
        let (detections, detections_l) = if consumes(TopicId::Detections) {
            let (i, l) = Inbox::open(node, TopicId::Detections, &detections_service(node)?)?;
            (Some(i), Some(l))
        } else {
            (None, None)
        };
        let (tracks, tracks_l) = if consumes(TopicId::Tracks) {
            let (i, l) = Inbox::open(node, TopicId::Tracks, &tracks_service(node)?)?;
            (Some(i), Some(l))
        } else {
            (None, None)
        };
        let (earth_frames, earth_frame_l) = if consumes(TopicId::EarthFrame) {
            let service = earth_frame_service(node, scenario.earth_px())?;
            let (mut i, l) = FrameInbox::open_on(node, TopicId::EarthFrame, &service)?;
            // The earth service verifies the pixel checksum; the orchestrator reads headers.
            i.verify_checksum = false;
            (Some(i), Some(l))
        } else {
            (None, None)
        };
        let (earth, earth_l) = if consumes(TopicId::EarthAttitude) {
            let service = earth_attitude_service(node)?;
            let (i, l) = Inbox::open(node, TopicId::EarthAttitude, &service)?;
            (Some(i), Some(l))
        } else {
            (None, None)
        };
        let (mut heartbeats, hb_l) =
            Inbox::open(node, TopicId::Heartbeat, &heartbeat_service(node)?)?;
        // A restarted service's heartbeats start again at seq 0.
        heartbeats.stats.peers_restart();
        let control = Outbox::open(node, TopicId::Control, &control_service(node)?, me)?;
        let acks = Outbox::open(node, TopicId::Ack, &ack_service(node)?, me)?;
        let mut expected = BTreeMap::new();
        for t in [
            TopicId::Frame,
            TopicId::Spectrum,
            TopicId::Truth,
            TopicId::Detections,
            TopicId::Tracks,
            TopicId::EarthFrame,
            TopicId::EarthAttitude,
        ] {
            if consumes(t) {
                expected.insert(t, deployment::expected_messages(scenario, t));
            }
        }
        Ok((
            Consumer {
                frames,
                spectra,
                truth,
                detections,
                tracks,
                earth_frames,
                earth,
                heartbeats,
                control,
                acks,
                frame_digest: Xxh3::new(),
                spectrum_digest: Xxh3::new(),
                truth_digest: Xxh3::new(),
                frame_latency_ns: vec![],
                frame_send_ns: vec![],
                spectrum_latency_ns: vec![],
                truths: vec![],
                detection_msgs: vec![],
                track_msgs: vec![],
                snapshot: None,
                snapshot_frame: 1,
                detections_digest: Xxh3::new(),
                tracks_digest: Xxh3::new(),
                earth_frame_digest: Xxh3::new(),
                earth_digest: Xxh3::new(),
                earth_msgs: vec![],
                earth_snapshot: None,
                earth_snapshot_frame: earth_snapshot_frame(scenario),
                light_curve: vec![],
                spectra_msgs: vec![],
                seen: BTreeMap::new(),
                expected,
                acked: BTreeMap::new(),
            },
            Listeners {
                heartbeat: hb_l,
                truth: truth_l,
                frame: frame_l,
                spectrum: spectrum_l,
                detections: detections_l,
                tracks: tracks_l,
                earth_frame: earth_frame_l,
                earth: earth_l,
            },
        ))
    }

    /// Orders `producer` to send a topic again to a restarted consumer.
    pub fn replay(&mut self, producer: ServiceId, order: Replay) -> Result<()> {
        self.control.send(Control::replay(producer, order), 0)?;
        Ok(())
    }

    /// Sends an in-band fault command to `service`.
    pub fn order_fault(&mut self, service: ServiceId, f: InBandFault) -> Result<()> {
        self.control.send(Control::fault(service, f), 0)?;
        Ok(())
    }

    /// Whether the orchestrator, a consumer of `topic`, has counted every output its producer
    /// reported dropping (`Drop`: as sequence gaps) or sending invalid (`Corrupt`: as
    /// malformed) on purpose.
    pub fn counted(&self, topic: TopicId, kind: FaultKind) -> bool {
        let (theirs, ours) = match kind {
            FaultKind::Drop => (DropReason::Injected, DropReason::Overflow),
            _ => (DropReason::Malformed, DropReason::Malformed),
        };
        let injected = self
            .reported(deployment::producer(topic), topic)
            .map_or(0, |c| c.dropped[theirs as usize]);
        let seen = self
            .own_stats()
            .iter()
            .find(|s| s.topic == topic)
            .map_or(0, |s| s.dropped[ours as usize]);
        injected > 0 && seen >= injected
    }

    /// Acknowledges again everything acknowledged so far: a restarted producer learns where
    /// the orchestrator is (its credit).
    pub fn refresh_acks(&mut self) -> Result<()> {
        for (topic, next_seq) in self.acked.clone() {
            self.send_ack(topic, next_seq)?;
        }
        Ok(())
    }

    pub fn command(&mut self, command: Command, target: u32) -> Result<()> {
        let c = Control {
            command: command as u32,
            target,
            ..Default::default()
        };
        self.control.send(c, 0)?;
        Ok(())
    }

    /// Reads every input, accounts for it, and acknowledges it (the producers' credit).
    pub fn poll(&mut self) -> Result<()> {
        self.poll_heartbeats()?;
        if let Some(frames) = self.frames.as_mut() {
            let (digest, lat) = (&mut self.frame_digest, &mut self.frame_latency_ns);
            let sent = &mut self.frame_send_ns;
            let (snap, want) = (&mut self.snapshot, self.snapshot_frame);
            frames.drain(|h, pixels, latency_ns| {
                digest.update(&h.meta.seq.to_le_bytes());
                digest.update(&h.pixels_xxh3.to_le_bytes());
                lat.push(latency_ns);
                sent.push((h.meta.seq, h.meta.send_mono_ns));
                if h.frame_index == want {
                    *snap = Some((h.frame_index, h.width_px, h.height_px, pixels.to_vec()));
                }
                Ok(())
            })?;
            let next = frames.stats.next_seq;
            self.ack(TopicId::Frame, next)?;
        }
        if let Some(spectra) = self.spectra.as_mut() {
            let (digest, lat) = (&mut self.spectrum_digest, &mut self.spectrum_latency_ns);
            let (curve, keep) = (&mut self.light_curve, &mut self.spectra_msgs);
            spectra.drain(|r| {
                keep.push(*r.msg);
                digest.update(&r.msg.content_xxh3.to_le_bytes());
                lat.push(r.latency_ns);
                let m = r.msg;
                let n = m.n_bands as usize;
                let pick = [0, n / 2, n - 1];
                curve.push((
                    m.meta.seq,
                    pick.map(|i| m.wavelength_nm[i]),
                    pick.map(|i| m.flux_w[i]),
                ));
                Ok(())
            })?;
            let next = spectra.stats.next_seq;
            self.ack(TopicId::Spectrum, next)?;
        }
        if let Some(inbox) = self.detections.as_mut() {
            let next = drain_keep(inbox, &mut self.detections_digest, &mut self.detection_msgs)?;
            self.ack(TopicId::Detections, next)?;
        }
        if let Some(inbox) = self.tracks.as_mut() {
            let next = drain_keep(inbox, &mut self.tracks_digest, &mut self.track_msgs)?;
            self.ack(TopicId::Tracks, next)?;
        }
        if let Some(frames) = self.earth_frames.as_mut() {
            let digest = &mut self.earth_frame_digest;
            let (snap, want) = (&mut self.earth_snapshot, self.earth_snapshot_frame);
            frames.drain(|h, pixels, _| {
                digest.update(&h.meta.seq.to_le_bytes());
                digest.update(&h.pixels_xxh3.to_le_bytes());
                if h.frame_index == want {
                    *snap = Some((h.frame_index, h.width_px, h.height_px, pixels.to_vec()));
                }
                Ok(())
            })?;
            let next = frames.stats.next_seq;
            self.ack(TopicId::EarthFrame, next)?;
        }
        if let Some(inbox) = self.earth.as_mut() {
            let (digest, keep) = (&mut self.earth_digest, &mut self.earth_msgs);
            inbox.drain(|r| {
                // The answers, not what they took: compute times differ between runs.
                let mut m = *r.msg;
                for method in &mut m.methods {
                    method.time_us = 0.0;
                }
                hash_pod(digest, &m);
                keep.push(*r.msg);
                Ok(())
            })?;
            let next = inbox.stats.next_seq;
            self.ack(TopicId::EarthAttitude, next)?;
        }
        let (digest, truths) = (&mut self.truth_digest, &mut self.truths);
        self.truth.drain(|r| {
            let t = r.msg;
            digest.update(&t.meta.seq.to_le_bytes());
            digest.update(&t.meta.t_ns.to_le_bytes());
            for s in &t.debris_state_lvlh[..t.n_debris as usize] {
                for v in s {
                    digest.update(&v.to_le_bytes());
                }
            }
            for v in (t.attitude_body_rest.iter())
                .chain(t.rate_deg_per_frame.iter())
                .chain([t.earth_beta_deg, t.earth_tilt_deg].iter())
            {
                digest.update(&v.to_le_bytes());
            }
            truths.push(*t);
            Ok(())
        })?;
        let next = self.truth.stats.next_seq;
        self.ack(TopicId::Truth, next)?;
        Ok(())
    }

    pub fn poll_heartbeats(&mut self) -> Result<()> {
        let seen = &mut self.seen;
        self.heartbeats.drain(|r| {
            if let Some(id) = ServiceId::from_u32(r.msg.meta.producer) {
                if !seen.contains_key(&id) {
                    tracing::debug!(service = id.name(), state = r.msg.state, "first heartbeat");
                }
                seen.insert(
                    id,
                    Seen {
                        heartbeat: *r.msg,
                        at: Instant::now(),
                    },
                );
            }
            Ok(())
        })?;
        Ok(())
    }

    fn ack(&mut self, topic: TopicId, next_seq: u64) -> Result<()> {
        // Send only when something new arrived.
        if self.acked.get(&topic) == Some(&next_seq) {
            return Ok(());
        }
        self.acked.insert(topic, next_seq);
        self.send_ack(topic, next_seq)
    }

    fn send_ack(&mut self, topic: TopicId, next_seq: u64) -> Result<()> {
        let a = Ack {
            topic: topic as u32,
            consumer: ServiceId::Orchestrator as u32,
            next_seq,
            ..Default::default()
        };
        self.acks.send(a, 0)?;
        Ok(())
    }

    /// Own statistics per consumed topic.
    pub fn own_stats(&self) -> Vec<&TopicStats> {
        let mut v: Vec<&TopicStats> = vec![];
        if let Some(f) = &self.frames {
            v.push(&f.stats);
        }
        if let Some(s) = &self.spectra {
            v.push(&s.stats);
        }
        v.push(&self.truth.stats);
        if let Some(d) = &self.detections {
            v.push(&d.stats);
        }
        if let Some(t) = &self.tracks {
            v.push(&t.stats);
        }
        if let Some(f) = &self.earth_frames {
            v.push(&f.stats);
        }
        if let Some(e) = &self.earth {
            v.push(&e.stats);
        }
        v
    }

    /// True once every expected message of every consumed topic is accounted for.
    pub fn complete(&self) -> bool {
        self.own_stats()
            .iter()
            .all(|s| s.next_seq >= self.expected_now(s.topic))
    }

    /// Messages of `topic` the run will carry: the scenario's count, less what the services
    /// upstream of it dropped with a counted reason (a detector publishes one message per frame
    /// it processed; a dropped or malformed frame makes none).
    pub fn expected_now(&self, topic: TopicId) -> u64 {
        let want = self.expected.get(&topic).copied().unwrap_or(0);
        let (service, input) = match topic {
            TopicId::Detections => (ServiceId::Detector, TopicId::Frame),
            TopicId::Tracks => (ServiceId::Tracker, TopicId::Detections),
            TopicId::EarthAttitude => (ServiceId::Earth, TopicId::EarthFrame),
            _ => return want,
        };
        let upstream = self.expected_now(input).min(want);
        let dropped = self
            .reported(service, input)
            .map_or(0, |c| c.dropped.iter().sum::<u64>());
        upstream.saturating_sub(dropped)
    }

    /// How many messages of `topic` the orchestrator has taken so far (0 if it does not
    /// consume it).
    pub fn carried(&self, topic: TopicId) -> u64 {
        self.own_stats()
            .iter()
            .find(|s| s.topic == topic)
            .map_or(0, |s| s.next_seq)
    }

    /// (accepted, expected) over all consumed topics, for progress display.
    pub fn progress(&self) -> (u64, u64) {
        let done: u64 = self.own_stats().iter().map(|s| s.next_seq).sum();
        let want: u64 = self.expected.values().sum();
        (done, want)
    }

    pub fn digests(&self) -> BTreeMap<TopicId, u64> {
        let mut m = BTreeMap::new();
        if self.frames.is_some() {
            m.insert(TopicId::Frame, self.frame_digest.digest());
        }
        if self.spectra.is_some() {
            m.insert(TopicId::Spectrum, self.spectrum_digest.digest());
        }
        m.insert(TopicId::Truth, self.truth_digest.digest());
        if self.detections.is_some() {
            m.insert(TopicId::Detections, self.detections_digest.digest());
        }
        if self.tracks.is_some() {
            m.insert(TopicId::Tracks, self.tracks_digest.digest());
        }
        if self.earth_frames.is_some() {
            m.insert(TopicId::EarthFrame, self.earth_frame_digest.digest());
        }
        if self.earth.is_some() {
            m.insert(TopicId::EarthAttitude, self.earth_digest.digest());
        }
        m
    }

    /// Counters a service reported for a topic in its last heartbeat.
    pub fn reported(&self, id: ServiceId, topic: TopicId) -> Option<TopicCounters> {
        self.seen.get(&id).and_then(|s| {
            s.heartbeat
                .topics
                .iter()
                .find(|c| c.topic == topic as u32)
                .copied()
        })
    }
}

/// The Earth frame kept for the annotated picture: the first at the angle nearest 20° (a ring
/// clear of the blind zone and of the image circle's edge).
fn earth_snapshot_frame(scenario: &Scenario) -> u64 {
    let Some(e) = &scenario.earth else {
        return u64::MAX;
    };
    let angles = e.angles_deg();
    let best = (0..angles.len())
        .min_by(|&a, &b| {
            (angles[a].abs() - 20.0)
                .abs()
                .total_cmp(&(angles[b].abs() - 20.0).abs())
        })
        .unwrap_or(0);
    best as u64 * e.images_per_angle as u64
}

/// Receives everything queued on `inbox`, folding each message into `digest` and keeping it;
/// returns the next expected sequence number (what to acknowledge).
fn drain_keep<T: shared_types::Message>(
    inbox: &mut Inbox<T>,
    digest: &mut Xxh3,
    keep: &mut Vec<T>,
) -> Result<u64> {
    inbox.drain(|r| {
        hash_pod(digest, r.msg);
        keep.push(*r.msg);
        Ok(())
    })?;
    Ok(inbox.stats.next_seq)
}

/// Folds a message's content into a digest, leaving out its send time (the only field that
/// differs between two runs of the same scenario and seed).
fn hash_pod<T: shared_types::Message>(digest: &mut Xxh3, msg: &T) {
    let mut copy = *msg;
    copy.meta_mut().send_mono_ns = 0;
    // Every wire type derives bytemuck::Pod (no padding, checked at compile time), so its bytes
    // are all initialised.
    digest.update(bytemuck::bytes_of(&copy));
}
