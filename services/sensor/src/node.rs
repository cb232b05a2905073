//! The sensor on the service skeleton: after `Start` it emits every stream of the scenario
//! ([`crate::streams`]) — in sim-clock mode as fast as the consumers' acknowledgements allow
//! (lockstep, nothing dropped), in strict simulated-time order over the streams; in realtime
//! mode paced by the wall clock — while answering laser-range requests. Message `k` of a stream
//! is a function of `k`, so a restarted sensor needs no state: in sim-clock mode it continues
//! from its checkpoint's accounting and makes again what a restarted consumer is replayed; in
//! realtime mode it continues each stream at the message the run's clock has come to (the
//! orchestrator's [`Command::Continue`]): what came due while it was down was never made, and
//! its consumers count the gap.

use std::path::Path;
use std::sync::Arc;
use std::time::Duration;

use anyhow::Result;
use glint_runtime::ports::{FrameOutbox, Outbox};
use glint_runtime::rpc::RangeServer;
use glint_runtime::waitloop::{Step, Wake};
use glint_runtime::{Io, NoInput, Output, Service, Setup, TopicStats};
use shared_types::deployment::{self, realtime_period_ns};
use shared_types::topics::IpcNode;
use shared_types::{Command, DropReason, Message, Scenario, ServiceId, TopicId, Truth};

use crate::recorded::{self, RecordedFrames, RecordedMessages, RecordedVisitor};
use crate::recording::Recording;
use crate::service_core::SensorCore;
use crate::streams::{
    next_in_time, EarthStream, FrameStream, MessageStream, PhotometryStream, SpectraStream,
    StereoStream, Stream,
};

/// Messages produced per wake-up before the loop checks control and acks again.
const BATCH: usize = 8;

/// A stream with the port it publishes on.
trait Emitter {
    fn stream(&self) -> &dyn Stream;
    fn out(&self) -> &dyn Output;
    fn output(&mut self) -> &mut dyn Output;
    /// Publishes the next message (rendered into the loan, or made whole); its truth.
    fn emit(&mut self) -> Result<Truth>;
    /// Messages it sends in all: the stream's, or fewer once ended ([`Emitter::end_at`]).
    fn end(&self) -> u64;
    /// Ends the stream after `messages` (or where it is, if it has sent more).
    fn end_at(&mut self, messages: u64);
    /// What paces it beside credit.
    fn pace(&self) -> Pace;

    fn topic(&self) -> TopicId {
        self.stream().topic()
    }
    fn stats(&self) -> &TopicStats {
        self.out().stats()
    }
    /// Index of the next message to emit.
    fn next_seq(&self) -> u64 {
        self.out().next_seq()
    }
    /// The simulated time of the next message, if the stream has one left.
    fn next_t_ns(&self) -> Option<u64> {
        let k = self.next_seq();
        (k < self.end()).then(|| self.stream().t_ns(k))
    }
    /// When the next message is due after `Start` [ns] (realtime, or a paced replay); `None`:
    /// as soon as it is its turn.
    fn due_ns(&self) -> Option<u64> {
        let k = self.next_seq();
        match self.pace() {
            Pace::Credit => None,
            Pace::Period(p) => Some(p * k),
            Pace::Speed(x) => {
                let t_ns = self.stream().t_ns(k.min(self.end().saturating_sub(1)));
                Some((t_ns as f64 / x) as u64)
            }
        }
    }
    /// Whether the next message is a replay (a consumer restarted).
    fn replaying(&self) -> bool {
        self.out().replaying()
    }
}

/// What paces a stream beside its consumers' credit.
#[derive(Debug, Clone, Copy)]
enum Pace {
    /// Credit alone (sim clock): as fast as the consumers take it.
    Credit,
    /// Realtime mode: one message every period [ns] ([`realtime_period_ns`]).
    Period(u64),
    /// A replay at a speed (`[replay] speed`): message `k` at its recorded simulated time
    /// (since the scenario's start, the same origin for every stream) over the speed.
    Speed(f64),
}

impl Pace {
    fn of(sc: &Scenario, topic: TopicId) -> Pace {
        let realtime = sc.clock == shared_types::scenario::Clock::Realtime;
        let period_ns = realtime_period_ns(sc, topic).filter(|_| realtime);
        match (period_ns, sc.replay.as_ref().map(|r| r.speed)) {
            (Some(p), _) => Pace::Period(p),
            (None, Some(x)) if x > 0.0 => Pace::Speed(x),
            (None, _) => Pace::Credit,
        }
    }
}

struct Frames<S: FrameStream> {
    stream: S,
    out: FrameOutbox,
    end: u64,
    pace: Pace,
}

impl<S: FrameStream + 'static> Frames<S> {
    /// The stream with its port, ending where the scenario says, paced in realtime mode.
    fn open(stream: S, node: &IpcNode, sc: &Scenario) -> Result<Box<dyn Emitter>> {
        let out = FrameOutbox::open(node, stream.topic(), sc)?;
        let (end, pace) = (stream.messages(), Pace::of(sc, stream.topic()));
        Ok(Box::new(Frames {
            stream,
            out,
            end,
            pace,
        }))
    }
}

impl<S: FrameStream> Emitter for Frames<S> {
    fn stream(&self) -> &dyn Stream {
        &self.stream
    }
    fn out(&self) -> &dyn Output {
        &self.out
    }
    fn output(&mut self) -> &mut dyn Output {
        &mut self.out
    }
    fn emit(&mut self) -> Result<Truth> {
        let k = self.out.next_seq();
        let stream = &self.stream;
        self.out
            .publish(stream.t_ns(k), |h, px| stream.render(k, h, px))?;
        Ok(stream.truth(k))
    }
    fn end(&self) -> u64 {
        self.end
    }
    fn end_at(&mut self, messages: u64) {
        self.end = self.end.min(messages.max(self.out.next_seq()));
    }
    fn pace(&self) -> Pace {
        self.pace
    }
}

struct Messages<S: MessageStream> {
    stream: S,
    out: Outbox<S::Msg>,
    end: u64,
    pace: Pace,
}

impl<S: MessageStream + 'static> Messages<S> {
    /// The stream with its port, ending where the scenario says, paced in realtime mode.
    fn open(stream: S, node: &IpcNode, sc: &Scenario) -> Result<Box<dyn Emitter>> {
        let out = Outbox::open(node, stream.topic(), ServiceId::Sensor)?;
        let (end, pace) = (stream.messages(), Pace::of(sc, stream.topic()));
        Ok(Box::new(Messages {
            stream,
            out,
            end,
            pace,
        }))
    }
}

impl<S: MessageStream> Emitter for Messages<S> {
    fn stream(&self) -> &dyn Stream {
        &self.stream
    }
    fn out(&self) -> &dyn Output {
        &self.out
    }
    fn output(&mut self) -> &mut dyn Output {
        &mut self.out
    }
    fn emit(&mut self) -> Result<Truth> {
        let k = self.out.next_seq();
        let (msg, truth) = self.stream.make(k)?;
        self.out.send(msg, self.stream.t_ns(k))?;
        Ok(truth)
    }
    fn end(&self) -> u64 {
        self.end
    }
    fn end_at(&mut self, messages: u64) {
        self.end = self.end.min(messages.max(self.out.next_seq()));
    }
    fn pace(&self) -> Pace {
        self.pace
    }
}

/// Every stream of `sc` with its port, in table order (the tie-break of the emission order):
/// the one list a new sensor mode joins.
fn emitters(setup: &Setup<'_>, core: &SensorCore) -> Result<Vec<Box<dyn Emitter>>> {
    let (node, sc): (_, &Scenario) = (setup.node, setup.scenario);
    if let Some(replay) = &sc.replay {
        return recorded_emitters(node, sc, &replay.recording);
    }
    let mut all: Vec<Box<dyn Emitter>> = vec![];
    if let Some(stream) = core.debris_stream() {
        all.push(Frames::open(stream, node, sc)?);
    }
    if let Some(sp) = &sc.spectra {
        all.push(Messages::open(SpectraStream::new(sp, sc.seed)?, node, sc)?);
    }
    if let Some(e) = &sc.earth {
        all.push(Frames::open(EarthStream::new(e, sc.seed), node, sc)?);
    }
    if let Some(st) = &sc.stereo {
        all.push(Messages::open(StereoStream::new(st, sc.seed), node, sc)?);
    }
    if let Some(p) = &sc.photometry {
        all.push(Messages::open(
            PhotometryStream::new(p, sc.seed)?,
            node,
            sc,
        )?);
    }
    all.sort_by_key(|e| e.topic());
    Ok(all)
}

/// `[replay]`: every stream of `sc` from the recording, in table order.
fn recorded_emitters(node: &IpcNode, sc: &Scenario, path: &str) -> Result<Vec<Box<dyn Emitter>>> {
    struct Port<'a> {
        node: &'a IpcNode,
        sc: &'a Scenario,
    }
    impl RecordedVisitor for Port<'_> {
        type Out = Box<dyn Emitter>;
        fn frames(self, stream: RecordedFrames) -> Result<Box<dyn Emitter>> {
            Frames::open(stream, self.node, self.sc)
        }
        fn messages<T: Message>(self, stream: RecordedMessages<T>) -> Result<Box<dyn Emitter>> {
            Messages::open(stream, self.node, self.sc)
        }
    }
    let recording = Arc::new(Recording::open(Path::new(path))?);
    let streams: Vec<TopicId> = deployment::outputs(sc, ServiceId::Sensor)
        .into_iter()
        .filter(|t| t.spec().truth.is_some())
        .collect();
    let names: Vec<&str> = streams.iter().map(|t| t.name()).collect();
    tracing::info!(recording = path, topics = ?names, "replaying from the recording");
    streams
        .into_iter()
        .map(|t| recorded::open(&recording, t, sc, Port { node, sc }))
        .collect()
}

pub struct SensorNode {
    core: SensorCore,
    streams: Vec<Box<dyn Emitter>>,
    truth: Outbox<Truth>,
    range: RangeServer,
    started_ns: Option<u64>,
    /// Realtime mode, a restarted incarnation: its clock is still to be set so that the
    /// message it continues at ([`Command::Continue`]) is due now.
    rejoin: bool,
    paused: bool,
}

impl Service for SensorNode {
    const ID: ServiceId = ServiceId::Sensor;
    type Input = NoInput;

    fn open(setup: &mut Setup<'_>) -> Result<(Self, NoInput)> {
        let (range, listener) = RangeServer::open(setup.node, Self::ID)?;
        setup.listen(listener);
        let truth = Outbox::open(setup.node, TopicId::Truth, Self::ID)?;
        let core = SensorCore::new(setup.scenario)?;
        let streams = emitters(setup, &core)?;
        tracing::info!(
            streams = ?streams.iter().map(|s| s.topic().name()).collect::<Vec<_>>(),
            clock = ?setup.scenario.clock,
            "sensor scenes built"
        );
        let sensor = SensorNode {
            core,
            streams,
            truth,
            range,
            started_ns: None,
            rejoin: setup.restarted
                && setup.scenario.clock == shared_types::scenario::Clock::Realtime,
            paused: false,
        };
        Ok((sensor, NoInput))
    }

    /// The streams in table order (the first is the main output: in-band drops and
    /// corruptions hit it), then the truth.
    /// Message `k` of a stream is a function of `k`: its ports' accounting is all its state.
    fn checkpoint(&self) -> Result<Option<Vec<u8>>> {
        Ok(Some(vec![]))
    }

    fn outputs(&mut self) -> Vec<&mut dyn Output> {
        let mut all: Vec<&mut dyn Output> = self.streams.iter_mut().map(|s| s.output()).collect();
        all.push(&mut self.truth);
        all
    }

    fn stats(&self) -> Vec<&TopicStats> {
        let mut all: Vec<&TopicStats> = self.streams.iter().map(|s| s.stats()).collect();
        all.extend([&self.truth.stats, &self.range.stats]);
        all
    }

    fn on_command(&mut self, io: &mut Io<'_>, cmd: Command) -> Result<()> {
        match cmd {
            Command::Start if self.started_ns.is_none() => self.started_ns = Some(io.now_ns()),
            Command::Pause => self.paused = true,
            Command::Resume => self.paused = false,
            _ => {}
        }
        Ok(())
    }

    fn on_end(&mut self, topic: TopicId, messages: u64) {
        for s in self.streams.iter_mut().filter(|s| s.topic() == topic) {
            s.end_at(messages);
            tracing::info!(topic = topic.name(), end = s.end(), "stream ended early");
        }
    }

    fn on_input(&mut self, _io: &mut Io<'_>, _: ()) -> Result<Result<(), DropReason>> {
        Ok(Ok(()))
    }

    fn on_tick(&mut self, io: &mut Io<'_>, _wakes: &[Wake]) -> Result<Step> {
        let core = &self.core;
        self.range.serve(|req| core.answer_range(req))?;
        let (Some(mut t0_ns), false) = (self.started_ns, self.paused) else {
            return Ok(Step::Wait);
        };
        if std::mem::take(&mut self.rejoin) {
            // The orchestrator continued each paced stream at the message due by the run's
            // clock (the ones due while it was down were never made): that one is due now,
            // and the rest keep the run's pace.
            let behind = (self.streams.iter()).filter_map(|s| s.due_ns()).min();
            t0_ns = io.now_ns().saturating_sub(behind.unwrap_or(0));
            self.started_ns = Some(t0_ns);
        }
        let mut next_wake_ns: Option<u64> = None;
        let mut produced = 0;
        for _ in 0..BATCH {
            let in_turn = next_in_time(self.streams.iter().map(|s| s.next_t_ns()));
            let mut progressed = false;
            for (i, stream) in self.streams.iter_mut().enumerate() {
                if stream.next_t_ns().is_none() {
                    continue;
                }
                let replay = stream.replaying();
                let paced = match stream.due_ns() {
                    Some(at) => {
                        let now = io.now_ns() - t0_ns;
                        if now < at {
                            let wait = at - now;
                            next_wake_ns = Some(next_wake_ns.map_or(wait, |w| w.min(wait)));
                        }
                        now >= at
                    }
                    None => true,
                };
                // Sim clock: its turn, credit for it, and credit for its truth (a message sent
                // again to a restarted consumer sends none).
                let due = paced
                    && (io.realtime || {
                        let truth_ok = io.allows(TopicId::Truth, self.truth.stats.published);
                        in_turn == Some(i)
                            && io.allows(stream.topic(), stream.next_seq())
                            && (truth_ok || replay)
                    });
                if !due {
                    continue;
                }
                io.pace()?;
                let t_ns = stream.next_t_ns().unwrap_or(0);
                let truth = stream.emit()?;
                // The truth was sent with the message's first emission.
                if !replay {
                    self.truth.send(truth, t_ns)?;
                }
                progressed = true;
            }
            if !progressed {
                break;
            }
            produced += 1;
        }
        let done = self.streams.iter().all(|s| s.next_t_ns().is_none());
        if done && io.state() == shared_types::Heartbeat::RUNNING {
            io.finish();
            tracing::info!("sensor finished producing");
        }
        // A full batch means there may be more to produce right away; otherwise wait for acks
        // (sim) or the next frame time (realtime), never spin.
        Ok(match next_wake_ns {
            _ if produced == BATCH => Step::WaitAtMost(Duration::ZERO),
            Some(ns) => Step::WaitAtMost(Duration::from_nanos(ns)),
            _ => Step::Wait,
        })
    }
}
