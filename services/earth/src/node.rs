//! The earth service on the service skeleton: Earth frames in (pixels read in place from
//! shared memory), one [`EarthAttitude`] out per frame.

use anyhow::{Context, Result};
use glint_runtime::ports::{FrameInbox, Outbox};
use glint_runtime::{Frame, Io, Output, Service, Setup};
use shared_types::{DropReason, EarthAttitude, ServiceId, TopicId};

use crate::service_core::EarthServiceCore;

pub struct EarthNode {
    core: EarthServiceCore,
    out: Outbox<EarthAttitude>,
}

impl Service for EarthNode {
    const ID: ServiceId = ServiceId::Earth;
    type Input = FrameInbox;

    fn open(setup: &mut Setup<'_>) -> Result<(Self, FrameInbox)> {
        let e = (setup.scenario.earth.as_ref())
            .context("the earth service needs an [earth] section")?;
        let (mut frames, listener) =
            FrameInbox::open(setup.node, TopicId::EarthFrame, setup.scenario)?;
        frames.verify_checksum = true;
        setup.listen(listener);
        let out = Outbox::open(setup.node, TopicId::EarthAttitude, Self::ID)?;
        let core = EarthServiceCore::new(e).context("earth.sigma_table")?;
        Ok((EarthNode { core, out }, frames))
    }

    fn outputs(&mut self) -> Vec<&mut dyn Output> {
        vec![&mut self.out]
    }

    fn stats(&self) -> Vec<&glint_runtime::TopicStats> {
        vec![&self.out.stats]
    }

    /// Each answer is a function of its frame alone (the core's masks and accumulators are
    /// scratch, rebuilt from the scenario): the ports' accounting is all a restart needs, and
    /// it is replayed only the frames after its checkpoint.
    fn checkpoint(&self) -> Result<Option<Vec<u8>>> {
        Ok(Some(vec![]))
    }

    fn on_input(&mut self, _io: &mut Io<'_>, frame: Frame<'_>) -> Result<Result<(), DropReason>> {
        let msg = match self.core.process(frame.header, frame.pixels) {
            Ok(m) => m,
            Err(reason) => return Ok(Err(reason)),
        };
        self.out.send(msg, frame.header.meta.t_ns)?;
        Ok(Ok(()))
    }
}
