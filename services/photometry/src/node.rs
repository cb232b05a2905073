//! The `photometry` service on the service skeleton: light-curve samples in, one
//! [`PhotometryEstimate`] out per sample (status `GATHERING` until the identification).

use std::sync::Arc;

use anyhow::{Context, Result};
use glint_physics::photometry::{Shape, SpecularDenominator};
use glint_runtime::ports::{Inbox, Outbox};
use glint_runtime::{checkpoint, Io, Output, Service, Setup, TopicStats};
use shared_types::scenario::PhotometryScenario;
use shared_types::{
    DropReason, PhotometryEstimate, PhotometryMatch, PhotometrySample, ServiceId, TopicId,
    MAX_MATCHES,
};

use crate::service_core::{Answer, Photometry, Settings};
use crate::{Sample, UkfSettings};

pub struct PhotometryNode {
    core: Photometry,
    shapes: Arc<Vec<(String, Shape)>>,
    settings: Settings,
    out: Outbox<PhotometryEstimate>,
}

/// The service's settings of a `[photometry]` section.
pub fn settings(p: &PhotometryScenario) -> Settings {
    Settings {
        identify_after_s: p.service.identify_after_s,
        axes: p.service.axes as usize,
        angles: p.service.angles as usize,
        ukf: UkfSettings {
            gamma: p.service.gamma,
            den: SpecularDenominator::Linares2014,
            ..UkfSettings::default()
        },
    }
}

impl Service for PhotometryNode {
    const ID: ServiceId = ServiceId::Photometry;
    type Input = Inbox<PhotometrySample>;

    fn open(setup: &mut Setup<'_>) -> Result<(Self, Inbox<PhotometrySample>)> {
        let p = (setup.scenario.photometry.as_ref())
            .context("the photometry service needs a [photometry] section")?;
        let shapes = Arc::new(crate::shapes::read_shapes(&p.shapes)?);
        let (input, listener) = Inbox::open(setup.node, TopicId::Photometry)?;
        setup.listen(listener);
        let out = Outbox::open(setup.node, TopicId::PhotometryEstimate, Self::ID)?;
        let settings = settings(p);
        let core = Photometry::new(shapes.clone(), settings);
        Ok((
            PhotometryNode {
                core,
                shapes,
                settings,
                out,
            },
            input,
        ))
    }

    fn outputs(&mut self) -> Vec<&mut dyn Output> {
        vec![&mut self.out]
    }

    fn stats(&self) -> Vec<&TopicStats> {
        vec![&self.out.stats]
    }

    fn checkpoint(&self) -> Result<Option<Vec<u8>>> {
        checkpoint::encode(&self.core.state()).map(Some)
    }

    fn restore(&mut self, state: &[u8]) -> Result<()> {
        let state = checkpoint::decode(state)?;
        self.core = Photometry::restore(self.shapes.clone(), self.settings, state);
        Ok(())
    }

    fn on_input(
        &mut self,
        _io: &mut Io<'_>,
        m: &PhotometrySample,
    ) -> Result<Result<(), DropReason>> {
        let t_s = m.meta.t_ns as f64 * 1e-9;
        let seen = (m.status == PhotometrySample::SEEN).then(|| Sample {
            t_s,
            mag: m.mag,
            sigma_mag: m.sigma_mag,
            sun: m.sun.into(),
            obs: m.obs.into(),
            range_m: m.range_m,
        });
        let answer = self.core.sample(t_s, seen);
        let msg = message(m.sample_index, &answer, &self.shapes);
        self.out.send(msg, m.meta.t_ns)?;
        Ok(Ok(()))
    }
}

/// The wire form of a sample's answer.
fn message(
    sample_index: u64,
    answer: &Answer<'_>,
    shapes: &[(String, Shape)],
) -> PhotometryEstimate {
    let mut msg = PhotometryEstimate {
        sample_index,
        ..PhotometryEstimate::default()
    };
    let (matching, filter, updated, fallbacks, restarts) = match answer {
        Answer::Gathering { tried } => {
            msg.status = match tried {
                true => PhotometryEstimate::UNIDENTIFIED,
                false => PhotometryEstimate::GATHERING,
            };
            return msg;
        }
        Answer::Tracking {
            matching,
            filter,
            updated,
            fallbacks,
            restarts,
        } => (matching, filter, updated, fallbacks, restarts),
    };
    msg.status = PhotometryEstimate::TRACKING;
    for (slot, m) in msg
        .matching
        .iter_mut()
        .zip(matching.iter().take(MAX_MATCHES))
    {
        let g = shapes.iter().position(|(n, _)| *n == m.geometry);
        *slot = PhotometryMatch {
            geometry: g.unwrap_or(0) as u32,
            _pad: 0,
            score: m.score,
            area_scale: m.area_scale,
            area_m2: m.area_m2,
            axis: m.axis.normalize().into(),
            spin_rad_s: m.spin_rad_s,
            t0_s: m.t_s,
        };
        msg.n_matching += 1;
    }
    let q = filter.q.into_inner();
    let q = if q.w < 0.0 { -q } else { q };
    msg.q_ib = [q.w, q.i, q.j, q.k];
    msg.w_body_rad_s = filter.w.into();
    let mut n = 0;
    for i in 0..6 {
        for j in i..6 {
            msg.covariance[n] = filter.p[(i, j)];
            n += 1;
        }
    }
    msg.updated = *updated as u32;
    msg.fallbacks = *fallbacks as u32;
    msg.restarts = *restarts;
    msg
}
