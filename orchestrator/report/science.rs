//! `science.digest_xxh3`: one digest of every result a run produced, so that two runs (a
//! faulted one and its fault-free baseline) compare in one value.

use std::collections::BTreeMap;

use shared_types::{SolveResponse, TopicId};

/// The run's results in one digest: every topic's digest, then every solve answer's content.
pub fn digest(topics: &BTreeMap<TopicId, u64>, solve: &[SolveResponse]) -> u64 {
    let mut h = xxhash_rust::xxh3::Xxh3::new();
    for (t, d) in topics {
        h.update(&(*t as u32).to_le_bytes());
        h.update(&d.to_le_bytes());
    }
    for r in solve {
        // The answer, not its transport: which call (request id, seq) got it depends on how
        // often a stage was asked before it was ready, or retried after a restart.
        let mut r = *r;
        r.meta = Default::default();
        r.request_id = 0;
        h.update(bytemuck::bytes_of(&r));
    }
    h.digest()
}
