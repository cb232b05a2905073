//! The detector on the service skeleton: frames in (pixels read in place from shared memory),
//! matched detections out, one message per frame.

use anyhow::{Context, Result};
use glint_runtime::ports::{FrameInbox, Outbox};
use glint_runtime::{checkpoint, Frame, Io, Output, Service, Setup};
use shared_types::{DropReason, ServiceId, TopicId};

use crate::service_core::DetectorCore;

pub struct DetectorNode {
    core: DetectorCore,
    out: Outbox<shared_types::Detections>,
}

impl Service for DetectorNode {
    const ID: ServiceId = ServiceId::Detector;
    type Input = FrameInbox;

    fn open(setup: &mut Setup<'_>) -> Result<(Self, FrameInbox)> {
        let cam =
            (setup.scenario.camera.as_ref()).context("the detector needs a [camera] section")?;
        let (mut frames, listener) = FrameInbox::open(setup.node, TopicId::Frame, setup.scenario)?;
        // Integrity of the pixels is checked on receipt (one xxh3 pass, ~0.1 ms per 1024² frame).
        frames.verify_checksum = true;
        setup.listen(listener);
        let out = Outbox::open(setup.node, TopicId::Detections, Self::ID)?;
        let core = DetectorCore::new(cam).map_err(|e| anyhow::anyhow!("{e}"))?;
        Ok((DetectorNode { core, out }, frames))
    }

    fn outputs(&mut self) -> Vec<&mut dyn Output> {
        vec![&mut self.out]
    }

    fn stats(&self) -> Vec<&glint_runtime::TopicStats> {
        vec![&self.out.stats]
    }

    fn checkpoint(&self) -> Result<Option<Vec<u8>>> {
        checkpoint::encode(&self.core.state()).map(Some)
    }

    fn restore(&mut self, state: &[u8]) -> Result<()> {
        self.core.restore(checkpoint::decode(state)?);
        Ok(())
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
