//! The tracker on the service skeleton: detections in, tracks out, one message per frame; the
//! laser is a request/response client of the sensor.

use std::time::{Duration, Instant};

use anyhow::{Context, Result};
use glint_runtime::ports::{Inbox, Outbox};
use glint_runtime::rpc::{CallOutcome, RangeClient};
use glint_runtime::{checkpoint, Io, Output, Service, Setup, TopicStats};
use shared_types::{
    Detections, DropReason, RangeRequest, RangeResponse, ServiceId, TopicId, Tracks,
};

use crate::service_core::{Laser, TrackerCore};

pub struct TrackerNode {
    core: TrackerCore,
    out: Outbox<Tracks>,
    client: Option<RangeClient>,
    /// How long one shot waits for its echo.
    timeout: Duration,
}

impl Service for TrackerNode {
    const ID: ServiceId = ServiceId::Tracker;
    type Input = Inbox<Detections>;

    fn open(setup: &mut Setup<'_>) -> Result<(Self, Inbox<Detections>)> {
        let cam =
            (setup.scenario.camera.as_ref()).context("the tracker needs a [camera] section")?;
        let (dets, listener) = Inbox::open(setup.node, TopicId::Detections)?;
        setup.listen(listener);
        let out = Outbox::open(setup.node, TopicId::Tracks, Self::ID)?;
        let client = match cam.tracker.laser {
            true => Some(RangeClient::open(setup.node, Self::ID)?),
            false => None,
        };
        let core = TrackerCore::new(cam).map_err(|e| anyhow::anyhow!("{e}"))?;
        let timeout = Duration::from_millis(cam.tracker.range_timeout_ms);
        Ok((
            TrackerNode {
                core,
                out,
                client,
                timeout,
            },
            dets,
        ))
    }

    fn outputs(&mut self) -> Vec<&mut dyn Output> {
        vec![&mut self.out]
    }

    fn stats(&self) -> Vec<&TopicStats> {
        vec![&self.out.stats]
    }

    /// The tracks and their filters, and the laser's next request id.
    fn checkpoint(&self) -> Result<Option<Vec<u8>>> {
        let next_id = self.client.as_ref().map(|c| c.next_id());
        checkpoint::encode(&(self.core.state(), next_id)).map(Some)
    }

    fn restore(&mut self, state: &[u8]) -> Result<()> {
        let (tracks, next_id): (_, Option<u64>) = checkpoint::decode(state)?;
        self.core.restore(tracks);
        if let (Some(c), Some(id)) = (self.client.as_mut(), next_id) {
            c.resume_ids_at(id);
        }
        Ok(())
    }

    fn rpc_wait_ns(&self) -> u64 {
        self.client.as_ref().map_or(0, |c| c.wait_ns())
    }

    fn on_input(&mut self, io: &mut Io<'_>, d: &Detections) -> Result<Result<(), DropReason>> {
        let msg = match self.client.as_mut() {
            Some(client) => {
                let mut laser = RpcLaser {
                    client,
                    io,
                    timeout: self.timeout,
                };
                self.core.process(d, &mut laser)?
            }
            None => self.core.process(d, &mut NoLaser)?,
        };
        self.out.send(msg, d.exposure_end_ns)?;
        Ok(Ok(()))
    }
}

/// A scenario without the laser.
struct NoLaser;

impl Laser for NoLaser {
    fn fire(&mut self, _req: RangeRequest, _t_ns: u64) -> Result<Option<RangeResponse>> {
        Ok(None)
    }
}

/// How long a sim-clock shot is retried before the run is given up on (the orchestrator fails
/// the run long before, when the sensor does not come back).
const LASER_RETRY_LIMIT: Duration = Duration::from_secs(600);

/// The sensor's laser over request/response. In sim-clock mode an unanswered shot (timed out,
/// or its server gone: the sensor restarting or stopped) is fired again with the same request
/// id, the service beating in between, until it is answered; simulated time waits for it.
struct RpcLaser<'a, 'b> {
    client: &'a mut RangeClient,
    io: &'a mut Io<'b>,
    timeout: Duration,
}

impl Laser for RpcLaser<'_, '_> {
    fn fire(&mut self, req: RangeRequest, t_ns: u64) -> Result<Option<RangeResponse>> {
        self.io.beat_if_due()?;
        let sim_clock = !self.io.realtime;
        let id = self.client.new_id();
        let t0 = Instant::now();
        let mut retries = 0u32;
        loop {
            let wait = match sim_clock {
                true => self.timeout.min(Duration::from_millis(100)),
                false => self.timeout,
            };
            let outcome = self
                .client
                .call_with_id(self.io.node, req, id, t_ns, wait)?;
            if let CallOutcome::Answered(resp) = outcome {
                if retries > 0 {
                    tracing::info!(request = id, retries, "laser shot answered after retries");
                }
                return Ok(Some(resp));
            }
            if !sim_clock {
                return Ok(None);
            }
            if t0.elapsed() > LASER_RETRY_LIMIT {
                anyhow::bail!("the laser did not answer request {id} for {LASER_RETRY_LIMIT:?}");
            }
            if retries == 0 {
                tracing::warn!(request = id, ?outcome, "laser shot unanswered; retrying");
            }
            retries += 1;
            if !self.io.keepalive()? {
                return Ok(None);
            }
            if !glint_runtime::waitloop::pause(self.io.node, Duration::from_millis(20)) {
                anyhow::bail!("terminated while waiting for the laser");
            }
        }
    }
}
