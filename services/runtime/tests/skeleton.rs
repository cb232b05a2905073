//! The service skeleton's contract, driven in-process: [`run_service`] runs a tiny service on
//! real iceoryx2 shared memory in a thread while the test plays its producer, its consumers and
//! the orchestrator. It checks what every service gets from the skeleton: the sim-clock credit
//! of its output (it takes no more inputs than its consumers have room for), the acks of its
//! input, a replay from its log to a restarted consumer, an in-band drop, and shutdown.

use std::time::{Duration, Instant};

use glint_runtime::ports::{FrameInbox, FrameOutbox, Inbox, Outbox};
use glint_runtime::{
    open_node, remove_shm, run_service, shm_entries, Frame, Io, Output, Service, ServiceArgs,
    Setup, TopicStats,
};
use shared_types::scenario::{Corruption, FaultKind};
use shared_types::topics::{create_all, credit_window};
use shared_types::{
    Ack, Command, Control, Detections, DropReason, Heartbeat, InBandFault, Replay, Scenario,
    ServiceId, TopicId,
};

/// A detector that finds nothing: one empty `Detections` per frame, on the skeleton.
struct Relay {
    out: Outbox<Detections>,
}

impl Service for Relay {
    const ID: ServiceId = ServiceId::Detector;
    type Input = FrameInbox;

    fn open(setup: &mut Setup<'_>) -> anyhow::Result<(Self, FrameInbox)> {
        let (frames, l) = FrameInbox::open(setup.node, TopicId::Frame, setup.scenario)?;
        setup.listen(l);
        let out = Outbox::open(setup.node, TopicId::Detections, Self::ID)?;
        Ok((Relay { out }, frames))
    }
    fn outputs(&mut self) -> Vec<&mut dyn Output> {
        vec![&mut self.out]
    }
    fn stats(&self) -> Vec<&TopicStats> {
        vec![&self.out.stats]
    }
    fn on_input(
        &mut self,
        _io: &mut Io<'_>,
        frame: Frame<'_>,
    ) -> anyhow::Result<Result<(), DropReason>> {
        let d = Detections {
            frame_index: frame.header.frame_index,
            exposure_end_ns: frame.header.meta.t_ns,
            ..Default::default()
        };
        self.out.send(d, frame.header.meta.t_ns)?;
        Ok(Ok(()))
    }
}

/// debris-geo with 64×64 frames and in-band faults obeyed: the relay's output has two
/// consumers (the orchestrator and the tracker), both played by the test.
fn scenario() -> Scenario {
    let text = include_str!("../../../scenarios/debris-geo.toml")
        .replace("width_px = 1024", "width_px = 64")
        .replace("height_px = 1024", "height_px = 64");
    let mut sc = Scenario::from_toml_str(&text, "debris-geo.toml (64×64)").unwrap();
    sc.faults.enabled = true;
    sc
}

/// The test's side of the deployment.
struct Harness {
    frames: FrameOutbox,
    detections: Inbox<Detections>,
    heartbeats: Inbox<Heartbeat>,
    acks_in: Inbox<Ack>,
    control: Outbox<Control>,
    acks_out: Outbox<Ack>,
    /// The relay's last ack of the frames.
    frames_acked: u64,
    frame_window: u64,
    last_beat: Option<Heartbeat>,
}

impl Harness {
    fn poll(&mut self) {
        self.detections.drain(|_| Ok(())).unwrap();
        let acked = &mut self.frames_acked;
        self.acks_in
            .drain(|r| {
                let a = r.msg;
                if a.topic == TopicId::Frame as u32 && a.consumer == ServiceId::Detector as u32 {
                    *acked = (*acked).max(a.next_seq);
                }
                Ok(())
            })
            .unwrap();
        let beat = &mut self.last_beat;
        self.heartbeats
            .drain(|r| {
                if r.msg.meta.producer == ServiceId::Detector as u32 {
                    *beat = Some(*r.msg);
                }
                Ok(())
            })
            .unwrap();
    }

    /// Polls until `done` holds, for at most 20 s (a deadline, not a timing assertion).
    fn until(&mut self, what: &str, mut done: impl FnMut(&Harness) -> bool) {
        let t0 = Instant::now();
        while !done(self) {
            assert!(t0.elapsed() < Duration::from_secs(20), "waited for {what}");
            std::thread::sleep(Duration::from_millis(2));
            self.poll();
        }
    }

    /// Feeds frames up to `n` in all (acknowledging the detections when `ack`) until `done`
    /// holds, for at most 20 s (a deadline, not a timing assertion).
    fn drive(&mut self, what: &str, n: u64, ack: bool, done: impl Fn(&Harness) -> bool) {
        let window = self.frame_window;
        let t0 = Instant::now();
        loop {
            self.feed(n, window);
            if ack {
                self.ack_detections();
            }
            self.poll();
            if done(self) {
                return;
            }
            assert!(t0.elapsed() < Duration::from_secs(20), "waited for {what}");
            std::thread::sleep(Duration::from_millis(2));
        }
    }

    /// Publishes frames up to `n` in all, within the relay's room (its frame window).
    fn feed(&mut self, n: u64, window: u64) {
        while self.frames.next_seq() < n && self.frames.next_seq() < self.frames_acked + window {
            let k = self.frames.next_seq();
            self.frames
                .publish(1_000 + k, |h, px| {
                    h.frame_index = k;
                    h.width_px = 64;
                    h.height_px = 64;
                    h.exposure_ns = 1;
                    px.fill(k as u16);
                })
                .unwrap();
        }
    }

    /// Acknowledges the detections taken so far, as both of their consumers.
    fn ack_detections(&mut self) {
        let next_seq = self.detections.stats.next_seq;
        for consumer in [ServiceId::Orchestrator, ServiceId::Tracker] {
            let a = Ack {
                topic: TopicId::Detections as u32,
                consumer: consumer as u32,
                next_seq,
                ..Default::default()
            };
            self.acks_out.send(a, 0).unwrap();
        }
    }

    fn command(&mut self, c: Control) {
        self.control.send(c, 0).unwrap();
    }
}

/// Removes the test's shared memory however the test ends (a failed assertion too).
struct Cleanup(String);

impl Drop for Cleanup {
    fn drop(&mut self) {
        remove_shm(&self.0);
    }
}

#[test]
fn the_skeleton_holds_credit_acks_replays_an_injected_drop_and_shuts_down() {
    let prefix = format!("glt{}sk_", std::process::id() % 100_000);
    let cleanup = Cleanup(prefix.clone());
    let sc = scenario();
    let window = credit_window(TopicId::Detections, &sc) as u64;
    let frame_window = credit_window(TopicId::Frame, &sc) as u64;
    {
        let node = open_node(&prefix, "test").unwrap();
        let _services = create_all(&node, &sc).unwrap();
        let (detections, _l1) = Inbox::open(&node, TopicId::Detections).unwrap();
        let (mut heartbeats, _l2) = Inbox::open(&node, TopicId::Heartbeat).unwrap();
        heartbeats.stats.peers_restart();
        let (acks_in, _l3) = Inbox::open(&node, TopicId::Ack).unwrap();
        let mut h = Harness {
            frames: FrameOutbox::open(&node, TopicId::Frame, &sc).unwrap(),
            detections,
            heartbeats,
            acks_in,
            control: Outbox::open(&node, TopicId::Control, ServiceId::Orchestrator).unwrap(),
            acks_out: Outbox::open(&node, TopicId::Ack, ServiceId::Orchestrator).unwrap(),
            frames_acked: 0,
            frame_window,
            last_beat: None,
        };
        let (p, s) = (prefix.clone(), sc.clone());
        let service = std::thread::spawn(move || {
            run_service::<Relay>(ServiceArgs {
                prefix: &p,
                scenario: &s,
                restarted: false,
            })
        });
        h.until("the relay's ready heartbeat", |h| {
            h.last_beat.is_some_and(|b| b.state >= Heartbeat::READY)
        });
        h.command(Control {
            command: Command::Start as u32,
            target: Control::ALL,
            ..Default::default()
        });

        // Credit: with its detections unacknowledged, the relay publishes one window and
        // takes no more frames than it can answer.
        let n = 3 * window;
        h.drive("one window of detections", n, false, |h| {
            h.detections.stats.next_seq >= window
        });
        for _ in 0..50 {
            h.feed(n, frame_window);
            std::thread::sleep(Duration::from_millis(4));
            h.poll();
        }
        assert_eq!(
            h.detections.stats.next_seq, window,
            "held by its consumers' credit"
        );
        // Its ack of what it took arrives in its own time (a deadline, not a duration).
        h.drive("the frames' ack", n, false, |h| h.frames_acked >= window);
        assert_eq!(h.detections.stats.next_seq, window, "still held");
        assert_eq!(
            h.frames_acked, window,
            "it took only the frames it could answer"
        );
        // Acknowledged, it goes on to the end: one answer per frame, in order, no gap.
        h.drive("every detection", n, true, |h| {
            h.detections.stats.next_seq >= n
        });
        assert_eq!(h.detections.stats.received, n);
        assert_eq!(h.detections.stats.dropped_total(), 0);
        h.until("the frames' acks", |h| h.frames_acked >= n);

        // A restarted tracker: the relay sends its whole log again (the consumers that have it
        // count duplicates), credit by credit.
        h.command(Control::replay(
            ServiceId::Detector,
            Replay {
                consumer: ServiceId::Tracker,
                topic: TopicId::Detections,
                from_seq: 0,
            },
        ));
        let t0 = Instant::now();
        while h.detections.stats.duplicates < n {
            assert!(
                t0.elapsed() < Duration::from_secs(20),
                "waited for the replay"
            );
            // The tracker's acks restart at 0 and follow what arrived again.
            let a = Ack {
                topic: TopicId::Detections as u32,
                consumer: ServiceId::Tracker as u32,
                next_seq: h.detections.stats.duplicates,
                ..Default::default()
            };
            h.acks_out.send(a, 0).unwrap();
            std::thread::sleep(Duration::from_millis(2));
            h.poll();
        }
        assert_eq!(
            h.detections.stats.duplicates, n,
            "every logged message, once"
        );
        assert_eq!(h.detections.stats.received, n, "nothing new");
        h.ack_detections();

        // An in-band drop of two outputs: two gaps downstream, two injected drops reported.
        h.command(Control::fault(
            ServiceId::Detector,
            InBandFault {
                kind: FaultKind::Drop,
                how: Corruption::Nan,
                count: 2,
                every: 1,
                delay_ms: 0,
                duration_ms: 0,
            },
        ));
        std::thread::sleep(Duration::from_millis(50));
        let m = n + 6;
        h.drive("the frames after the fault", m, true, |h| {
            h.detections.stats.next_seq >= m
        });
        assert_eq!(h.detections.stats.received, n + 4);
        assert_eq!(h.detections.stats.dropped[DropReason::Overflow as usize], 2);
        h.until("a heartbeat reporting the injected drops", |h| {
            h.last_beat.is_some_and(|b| {
                b.topics.iter().any(|c| {
                    c.topic == TopicId::Detections as u32
                        && c.dropped[DropReason::Injected as usize] == 2
                })
            })
        });

        // Shutdown: a last heartbeat, and the service returns.
        h.command(Control {
            command: Command::Shutdown as u32,
            target: Control::ALL,
            ..Default::default()
        });
        h.until("the stopping heartbeat", |h| {
            h.last_beat.is_some_and(|b| b.state == Heartbeat::STOPPING)
        });
        service.join().unwrap().unwrap();
    }
    drop(cleanup);
    assert!(shm_entries(&prefix).is_empty());
}
