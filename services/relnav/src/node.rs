//! The relnav service on the service skeleton: stereo epochs in, one [`RelNavEstimate`] out
//! per epoch (status `STARTING` while the filter starts from the measurements).

use anyhow::{Context, Result};
use glint_runtime::ports::{Inbox, Outbox};
use glint_runtime::{checkpoint, Io, Output, Service, Setup, TopicStats};
use shared_types::{DropReason, RelNavEstimate, ServiceId, Stereo, TopicId};

use crate::filter::FeatureObs;
use crate::model::{Rig, N_ERR};
use crate::service_core::{Estimate, RelNav, Settings};

pub struct RelNavNode {
    core: RelNav,
    rig: Rig,
    settings: Settings,
    out: Outbox<RelNavEstimate>,
}

impl Service for RelNavNode {
    const ID: ServiceId = ServiceId::RelNav;
    type Input = Inbox<Stereo>;

    fn open(setup: &mut Setup<'_>) -> Result<(Self, Inbox<Stereo>)> {
        let s = (setup.scenario.stereo.as_ref())
            .context("the relnav service needs a [stereo] section")?;
        let (input, listener) = Inbox::open(setup.node, TopicId::Stereo)?;
        setup.listen(listener);
        let out = Outbox::open(setup.node, TopicId::RelNav, Self::ID)?;
        let (rig, settings) = (crate::scenario::rig(s), crate::scenario::settings(s));
        let core = RelNav::new(rig.clone(), settings, crate::scenario::start(s));
        Ok((
            RelNavNode {
                core,
                rig,
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
        self.core = RelNav::restore(self.rig.clone(), self.settings, state);
        Ok(())
    }

    fn on_input(&mut self, _io: &mut Io<'_>, m: &Stereo) -> Result<Result<(), DropReason>> {
        let obs: Vec<FeatureObs> = m
            .seen()
            .iter()
            .map(|f| FeatureObs {
                feature: f.feature as usize,
                z: f.z,
            })
            .collect();
        let t_s = m.meta.t_ns as f64 * 1e-9;
        let est = self.core.epoch(t_s, &obs);
        let msg = message(m.epoch_index, est.as_ref(), &self.core);
        self.out.send(msg, m.meta.t_ns)?;
        Ok(Ok(()))
    }
}

/// The wire form of an epoch's answer.
fn message(epoch_index: u64, est: Option<&Estimate>, core: &RelNav) -> RelNavEstimate {
    let c = core.counters;
    let mut msg = RelNavEstimate {
        epoch_index,
        starts: c.starts as u32,
        diverged: c.diverged as u32,
        numerical_failures: c.numerical_failures as u32,
        ..RelNavEstimate::default()
    };
    let Some(e) = est else {
        return msg;
    };
    msg.status = match e.started {
        true => RelNavEstimate::STARTED,
        false => RelNavEstimate::RUNNING,
    };
    msg.used = e.update.used as u32;
    msg.rejected = e.update.rejected as u32;
    msg.dof = e.update.dof as u32;
    msg.nis = e.update.nis;
    let q = e.x.q_ct.into_inner();
    let q = if q.w < 0.0 { -q } else { q };
    msg.q_ct = [q.w, q.i, q.j, q.k];
    msg.w_t_rad_s = e.x.w_t.into();
    msg.k = e.x.k.into();
    msg.rho_o_m = e.x.rho_o.into();
    msg.v_o_m_s = e.x.v_o.into();
    let mut n = 0;
    for i in 0..N_ERR {
        for j in i..N_ERR {
            msg.covariance[n] = e.p[(i, j)];
            n += 1;
        }
    }
    msg
}
