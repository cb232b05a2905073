//! The sensor on the service skeleton: after `Start` it produces camera frames, spectra, Earth
//! frames and truth — in
//! sim-clock mode as fast as the consumers' acknowledgements allow (lockstep, nothing dropped),
//! in realtime mode frames paced by the wall clock — while answering laser-range requests.
//! A restarted sensor produces everything again from the start (rendering is stateless), and
//! its consumers skip what they already have as duplicates.

use std::time::Duration;

use anyhow::Result;
use glint_runtime::ports::{FrameOutbox, Outbox};
use glint_runtime::rpc::RangeServer;
use glint_runtime::waitloop::{Step, Wake};
use glint_runtime::{Io, NoInput, Output, Service, Setup, TopicStats};
use shared_types::{Command, DropReason, ServiceId, Spectrum, TopicId, Truth};

use crate::service_core::{Emission, SensorCore};

/// Messages produced per wake-up before the loop checks control and acks again.
const BATCH: usize = 8;

pub struct SensorNode {
    core: SensorCore,
    frames: Option<FrameOutbox>,
    spectra: Option<Outbox<Spectrum>>,
    earth: Option<FrameOutbox>,
    truth: Outbox<Truth>,
    range: RangeServer,
    /// Realtime: frame `k` is due `k` frame periods after `Start`.
    frame_period_ns: u64,
    earth_period_ns: u64,
    started_ns: Option<u64>,
    paused: bool,
}

impl Service for SensorNode {
    const ID: ServiceId = ServiceId::Sensor;
    type Input = NoInput;

    fn open(setup: &mut Setup<'_>) -> Result<(Self, NoInput)> {
        let (node, sc) = (setup.node, setup.scenario);
        let (range, listener) = RangeServer::open(node, Self::ID)?;
        setup.listen(listener);
        let truth = Outbox::open(node, TopicId::Truth, Self::ID)?;
        let frames = match &sc.camera {
            Some(_) => Some(FrameOutbox::open(node, TopicId::Frame, sc)?),
            None => None,
        };
        let spectra = match &sc.spectra {
            Some(_) => Some(Outbox::open(node, TopicId::Spectrum, Self::ID)?),
            None => None,
        };
        let earth = match &sc.earth {
            Some(_) => Some(FrameOutbox::open(node, TopicId::EarthFrame, sc)?),
            None => None,
        };
        let core = SensorCore::new(sc)?;
        tracing::info!(
            core.n_frames,
            core.n_spectra,
            core.n_earth,
            ?sc.clock,
            "sensor scenes built"
        );
        let sensor = SensorNode {
            core,
            frames,
            spectra,
            earth,
            truth,
            range,
            frame_period_ns: sc.camera.as_ref().map_or(0, |c| c.frame_period_ns()),
            earth_period_ns: (sc.earth.as_ref()).map_or(0, |e| e.exposure_end_ns(0)),
            started_ns: None,
            paused: false,
        };
        Ok((sensor, NoInput))
    }

    /// Camera frames first (the main output: in-band drops and corruptions hit it), then
    /// spectra, then Earth frames.
    fn outputs(&mut self) -> Vec<&mut dyn Output> {
        let mut all: Vec<&mut dyn Output> = vec![];
        if let Some(f) = self.frames.as_mut() {
            all.push(f);
        }
        if let Some(s) = self.spectra.as_mut() {
            all.push(s);
        }
        if let Some(e) = self.earth.as_mut() {
            all.push(e);
        }
        all.push(&mut self.truth);
        all
    }

    fn stats(&self) -> Vec<&TopicStats> {
        let f = self.frames.as_ref().map(|f| &f.stats);
        let s = self.spectra.as_ref().map(|s| &s.stats);
        let e = self.earth.as_ref().map(|e| &e.stats);
        [f, s, e, Some(&self.truth.stats), Some(&self.range.stats)]
            .into_iter()
            .flatten()
            .collect()
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

    fn on_input(&mut self, _io: &mut Io<'_>, _: ()) -> Result<Result<(), DropReason>> {
        Ok(Ok(()))
    }

    fn on_tick(&mut self, io: &mut Io<'_>, _wakes: &[Wake]) -> Result<Step> {
        let core = &self.core;
        self.range.serve(|req| core.answer_range(req))?;
        let (Some(t0_ns), false) = (self.started_ns, self.paused) else {
            return Ok(Step::Wait);
        };
        let mut next_wake_ns: Option<u64> = None;
        let mut produced = 0;
        for _ in 0..BATCH {
            let nf = self.frames.as_ref().map_or(u64::MAX, |f| f.next_seq());
            let ns = self.spectra.as_ref().map_or(u64::MAX, |s| s.next_seq());
            let ne = self.earth.as_ref().map_or(u64::MAX, |e| e.next_seq());
            let next = self.core.next(nf, ns, ne);
            let frame_first = matches!(next, Some(Emission::Frame { .. }));
            let spectrum_first = matches!(next, Some(Emission::Spectrum { .. }));
            let earth_first = matches!(next, Some(Emission::Earth { .. }));
            let mut progressed = false;
            if let (Some(Emission::Frame { k, t_ns }), Some(out)) =
                (self.core.frame(nf), self.frames.as_mut())
            {
                let turn = Turn {
                    k,
                    t_ns,
                    in_turn: frame_first,
                    topic: TopicId::Frame,
                    period_ns: self.frame_period_ns,
                    t0_ns,
                };
                let core = &self.core;
                progressed |= emit_frame(
                    io,
                    out,
                    &mut self.truth,
                    &turn,
                    &mut next_wake_ns,
                    |h, px| core.render_frame(k, h, px),
                    || core.frame_truth(k),
                )?;
            }
            if let (Some(Emission::Spectrum { k, .. }), Some(out)) =
                (self.core.spectrum_at(ns), self.spectra.as_mut())
            {
                let replay = out.replaying();
                let truth_ok = io.allows(TopicId::Truth, self.truth.stats.published);
                let due = io.realtime
                    || (spectrum_first && io.allows(TopicId::Spectrum, k) && (replay || truth_ok));
                if due {
                    io.pace()?;
                    let (sp, truth, t_ns) = self.core.spectrum(k)?;
                    out.send(sp, t_ns)?;
                    if !replay {
                        self.truth.send(truth, t_ns)?;
                    }
                    progressed = true;
                }
            }
            if let (Some(Emission::Earth { k, t_ns }), Some(out)) =
                (self.core.earth_at(ne), self.earth.as_mut())
            {
                let turn = Turn {
                    k,
                    t_ns,
                    in_turn: earth_first,
                    topic: TopicId::EarthFrame,
                    period_ns: self.earth_period_ns,
                    t0_ns,
                };
                let core = &self.core;
                progressed |= emit_frame(
                    io,
                    out,
                    &mut self.truth,
                    &turn,
                    &mut next_wake_ns,
                    |h, px| core.render_earth(k, h, px),
                    || core.earth_truth(k),
                )?;
            }
            if !progressed {
                break;
            }
            produced += 1;
        }
        let frames_done = self
            .frames
            .as_ref()
            .is_none_or(|f| f.next_seq() >= self.core.n_frames);
        let spectra_done =
            (self.spectra.as_ref()).is_none_or(|s| s.next_seq() >= self.core.n_spectra);
        let earth_done = (self.earth.as_ref()).is_none_or(|e| e.next_seq() >= self.core.n_earth);
        if frames_done
            && spectra_done
            && earth_done
            && io.state() == shared_types::Heartbeat::RUNNING
        {
            io.finish();
            tracing::info!("sensor finished producing");
        }
        // A full batch means there may be more to produce right away; otherwise wait for acks
        // (sim) or the next frame time (realtime), never spin.
        Ok(match next_wake_ns {
            _ if produced == BATCH => Step::WaitAtMost(Duration::ZERO),
            Some(ns) if io.realtime => Step::WaitAtMost(Duration::from_nanos(ns)),
            _ => Step::Wait,
        })
    }
}

/// Frame `k` of one frame stream (the camera's or the Earth sensor's), at `t_ns`.
struct Turn {
    k: u64,
    t_ns: u64,
    /// Whether it is next in simulated-time order of all the sensor's streams.
    in_turn: bool,
    topic: TopicId,
    /// Realtime: frame `k` is due `k` periods after `Start` (`t0_ns`).
    period_ns: u64,
    t0_ns: u64,
}

/// Publishes the frame of `turn` when it is due — in realtime by the wall clock, in sim-clock
/// mode when it is in turn and its topic and the truth have credit — rendered in place, and
/// its truth unless it is a replay (a restarted consumer; the truth was sent once). Whether it
/// was published.
fn emit_frame(
    io: &mut Io<'_>,
    out: &mut FrameOutbox,
    truth: &mut Outbox<Truth>,
    turn: &Turn,
    next_wake_ns: &mut Option<u64>,
    render: impl FnOnce(&mut shared_types::FrameHeader, &mut [u16]),
    truth_of: impl FnOnce() -> Option<Truth>,
) -> Result<bool> {
    let replay = out.replaying();
    let due = if io.realtime {
        let (at, now) = (turn.period_ns * turn.k, io.now_ns() - turn.t0_ns);
        if now < at {
            *next_wake_ns = Some(next_wake_ns.map_or(at - now, |w| w.min(at - now)));
        }
        now >= at
    } else {
        let truth_ok = io.allows(TopicId::Truth, truth.stats.published);
        turn.in_turn && io.allows(turn.topic, turn.k) && (truth_ok || replay)
    };
    if !due {
        return Ok(false);
    }
    io.pace()?;
    out.publish(turn.t_ns, render)?;
    if let (false, Some(t)) = (replay, truth_of()) {
        truth.send(t, turn.t_ns)?;
    }
    Ok(true)
}
