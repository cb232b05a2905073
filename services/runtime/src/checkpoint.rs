//! Checkpoints (docs/adr/0036): a service's state after the inputs it has taken, with the
//! accounting of its input and outputs, stored where its next incarnation finds it. A restarted
//! service restores its last checkpoint and is replayed only the inputs that came after it, so
//! recovery costs what one checkpoint interval costs, however long the run has been.
//!
//! A checkpoint is one file per service in `/dev/shm` (memory, not disk), named with the
//! deployment's prefix, so that `glint clean` and every leftover check find it. It is written
//! whole to a temporary name and renamed: a crash mid-write leaves the previous one. Its
//! contents are bincode (serde): the service's state is the service's own type, which its node
//! encodes with [`encode`].

use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::{anyhow, bail, Context, Result};
use serde::{de::DeserializeOwned, Deserialize, Serialize};
use shared_types::{ServiceId, CONTRACT_VERSION};

use crate::stats::StatsSnapshot;

/// One service's checkpoint.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Checkpoint {
    pub contract: u32,
    pub service: u32,
    /// The input's accounting: every message below its `next_seq` is in `state`.
    pub input: Option<StatsSnapshot>,
    pub outputs: Vec<OutputSnapshot>,
    /// The service's own state ([`crate::Service::checkpoint`]).
    pub state: Vec<u8>,
}

/// An output at a checkpoint: its accounting, its consumers' credit, and (a logged output)
/// the messages a consumer may still be sent again.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct OutputSnapshot {
    pub stats: StatsSnapshot,
    /// Per consumer (`ServiceId` as u32): acknowledged up to, and covered by its checkpoint up to.
    pub credit: Vec<(u32, u64, u64)>,
    /// Seq of the log's first message, and the log's messages as bytes.
    pub log_base: u64,
    pub log: Vec<u8>,
}

/// When to take one: every `every_inputs` inputs taken (a source: messages sent) or every
/// `every`, whichever comes first, once there is something new.
#[derive(Debug, Clone, Copy)]
pub struct Policy {
    pub every_inputs: u64,
    pub every: Duration,
}

/// Whether one is due, and where the last one was.
#[derive(Debug)]
pub struct Schedule {
    policy: Policy,
    last_at: Instant,
    last_progress: u64,
    /// Checkpoints written by this incarnation.
    pub taken: u64,
}

impl Schedule {
    pub fn new(policy: Policy, progress: u64) -> Self {
        Schedule {
            policy,
            last_at: Instant::now(),
            last_progress: progress,
            taken: 0,
        }
    }

    /// Due at `progress` (inputs taken, or messages sent by a source)?
    pub fn due(&self, progress: u64) -> bool {
        let new = progress.saturating_sub(self.last_progress);
        new > 0 && (new >= self.policy.every_inputs || self.last_at.elapsed() >= self.policy.every)
    }

    /// Inputs to take, at `progress`, before a checkpoint is due by count (at least one): a
    /// service takes its inputs in batches no longer than that, so that a checkpoint falls
    /// every `every_inputs` inputs and not only where a batch happens to end.
    pub fn remaining(&self, progress: u64) -> usize {
        let new = progress.saturating_sub(self.last_progress);
        self.policy.every_inputs.saturating_sub(new).max(1) as usize
    }

    pub fn taken_at(&mut self, progress: u64) {
        self.last_at = Instant::now();
        self.last_progress = progress;
        self.taken += 1;
    }
}

/// Where `service` of the deployment `prefix` keeps its checkpoint.
pub fn path(prefix: &str, service: ServiceId) -> PathBuf {
    let dir = std::path::Path::new("/dev/shm");
    let dir = if dir.is_dir() {
        dir.to_path_buf()
    } else {
        std::env::temp_dir()
    };
    dir.join(format!("{prefix}{}.checkpoint", service.name()))
}

/// A service's state as checkpoint bytes.
pub fn encode<T: Serialize>(state: &T) -> Result<Vec<u8>> {
    bincode::serde::encode_to_vec(state, bincode::config::standard())
        .map_err(|e| anyhow!("encoding a checkpoint: {e}"))
}

/// Checkpoint bytes as a service's state.
pub fn decode<T: DeserializeOwned>(bytes: &[u8]) -> Result<T> {
    let (state, read) = bincode::serde::decode_from_slice(bytes, bincode::config::standard())
        .map_err(|e| anyhow!("decoding a checkpoint: {e}"))?;
    if read != bytes.len() {
        bail!("a checkpoint with {} bytes left over", bytes.len() - read);
    }
    Ok(state)
}

impl Checkpoint {
    /// Writes it whole, then renames it over the previous one.
    pub fn write(&self, prefix: &str, service: ServiceId) -> Result<()> {
        let path = path(prefix, service);
        let tmp = path.with_extension("checkpoint.tmp");
        std::fs::write(&tmp, encode(self)?).with_context(|| format!("{}", tmp.display()))?;
        std::fs::rename(&tmp, &path).with_context(|| format!("{}", path.display()))?;
        Ok(())
    }

    /// The last checkpoint of `service`, if it has one of this contract.
    pub fn read(prefix: &str, service: ServiceId) -> Result<Option<Checkpoint>> {
        let path = path(prefix, service);
        let bytes = match std::fs::read(&path) {
            Ok(b) => b,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
            Err(e) => return Err(e).with_context(|| format!("{}", path.display())),
        };
        let c: Checkpoint = decode(&bytes).with_context(|| format!("{}", path.display()))?;
        if c.contract != CONTRACT_VERSION || c.service != service as u32 {
            bail!(
                "{}: a checkpoint of contract {} for service {}, not of contract {CONTRACT_VERSION} for {}",
                path.display(),
                c.contract,
                c.service,
                service.name()
            );
        }
        Ok(Some(c))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn due_every_n_inputs_or_after_the_interval_once_there_is_something_new() {
        let mut s = Schedule::new(
            Policy {
                every_inputs: 10,
                every: Duration::from_secs(3600),
            },
            5,
        );
        assert!(!s.due(5) && !s.due(14));
        assert!(s.due(15));
        s.taken_at(15);
        assert!(!s.due(15));
        let mut t = Schedule::new(
            Policy {
                every_inputs: 1000,
                every: Duration::ZERO,
            },
            0,
        );
        assert!(!t.due(0), "nothing new");
        assert!(t.due(1));
        t.taken_at(1);
        assert_eq!(t.taken, 1);
    }

    #[test]
    fn state_round_trips_to_the_bit() {
        let state = (
            vec![0.1f64, f64::NAN, -0.0, 1e-310],
            Some(7u64),
            "track".to_string(),
        );
        let back: (Vec<f64>, Option<u64>, String) = decode(&encode(&state).unwrap()).unwrap();
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&back.0), bits(&state.0));
        assert_eq!((back.1, back.2), (state.1, state.2));
        assert!(
            decode::<u64>(&[0xff; 3]).is_err(),
            "garbage is an error, not a panic"
        );
    }
}
