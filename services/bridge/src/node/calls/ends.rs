//! The two ends of a call across hosts: [`Serve`] on the caller's host, [`Answer`] on the
//! server's.

use std::time::Duration;

use anyhow::{anyhow, Result};
use glint_runtime::rpc::{CallOutcome, Pending, Request, Rpc, RpcClient, RpcServer};
use iceoryx2::port::listener::Listener;
use shared_types::topics::Ipc;
use shared_types::{Message, TopicId};

use super::{CallEnd, Counts, Side, Wire};

/// The caller's host: the bridge serves the call here.
pub(super) struct Serve<R: Rpc> {
    pub(super) server: RpcServer<R>,
    pub(super) requests: Listener<Ipc>,
    pub(super) wire: Wire,
    /// Requests put across and not yet answered, by id: one per id, at most `in_flight`.
    pub(super) waiting: Vec<(u64, Request<R>)>,
    /// The most requests the call keeps in flight per client (the table's `in_flight`), as
    /// many as iceoryx2 lets a server hold.
    pub(super) in_flight: usize,
    pub(super) counts: Counts,
}

impl<R: Rpc> CallEnd for Serve<R> {
    fn topic(&self) -> TopicId {
        R::TOPIC
    }
    fn side(&self) -> Side {
        Side::Serve
    }

    fn step(&mut self) -> Result<()> {
        let _ = self.requests.try_wait(|_| {});
        // Calls their caller gave up (timed out in realtime, or ended) are let go: in realtime
        // nobody asks again, and each held request is one iceoryx2 lets the server hold.
        let before = self.waiting.len();
        self.waiting.retain(|(_, r)| r.is_connected());
        self.counts.abandoned += (before - self.waiting.len()) as u64;
        loop {
            // Room for one more: at the limit the oldest goes (its caller has asked again).
            if self.waiting.len() >= self.in_flight {
                self.waiting.remove(0);
                self.counts.abandoned += 1;
            }
            let Some(req) = self.server.take_request()? else {
                break;
            };
            self.counts.taken += 1;
            let id = req.payload.meta().seq;
            // Asked again (its answer was late, or lost): the caller gave up the first one.
            let before = self.waiting.len();
            self.waiting.retain(|(w, _)| *w != id);
            self.counts.abandoned += (before - self.waiting.len()) as u64;
            // Put or not (the link congested: dropped, never waited for), it is held: its
            // caller asks again if no answer comes.
            self.wire.put(bytemuck::bytes_of(&req.payload));
            self.waiting.push((id, req));
        }
        Ok(())
    }

    fn take(&mut self, payload: &[u8], attachment: Option<&[u8]>) {
        let resp: R::Resp = match self.wire.read(payload, attachment) {
            Ok(r) => r,
            Err(why) => return refused(&mut self.counts, R::TOPIC, &why),
        };
        let id = R::response_id(&resp);
        let Some(at) = self.waiting.iter().position(|(w, _)| *w == id) else {
            // Its caller asked again and this is the first attempt's answer, or a repeat.
            self.counts.late += 1;
            return;
        };
        let (_, req) = self.waiting.swap_remove(at);
        match self.server.forward(req, resp) {
            Ok(()) => self.counts.answered += 1,
            // The caller stopped waiting (timed out, restarted): it asks again.
            Err(e) => {
                tracing::debug!(topic = R::TOPIC.name(), "answer not passed on: {e:#}");
                self.counts.abandoned += 1;
            }
        }
    }

    fn counts(&self) -> Counts {
        self.counts
    }

    fn busy(&self) -> bool {
        !self.waiting.is_empty()
    }

    fn wire(&self) -> &Wire {
        &self.wire
    }

    fn wait_for_caller(&self, timeout: Duration) -> Result<()> {
        (self.requests.timed_wait(|_| {}, timeout))
            .map(|_| ())
            .map_err(|e| anyhow!("{} request wait: {e:?}", R::TOPIC.name()))
    }
}

/// The server's host: the bridge asks the server what comes across.
pub(super) struct Answer<R: Rpc> {
    pub(super) client: RpcClient<R>,
    pub(super) wire: Wire,
    pub(super) pending: Vec<Pending<R>>,
    /// The most requests the call keeps in flight per client (the table's `in_flight`).
    pub(super) in_flight: usize,
    pub(super) counts: Counts,
}

impl<R: Rpc> CallEnd for Answer<R> {
    fn topic(&self) -> TopicId {
        R::TOPIC
    }
    fn side(&self) -> Side {
        Side::Answer
    }

    fn step(&mut self) -> Result<()> {
        let mut i = 0;
        while i < self.pending.len() {
            match self.client.poll(&self.pending[i])? {
                None => i += 1,
                Some(CallOutcome::Answered(resp)) => {
                    self.pending.swap_remove(i);
                    match self.wire.put(bytemuck::bytes_of(&resp)) {
                        true => self.counts.answered += 1,
                        // Dropped on a congested link: its caller asks again.
                        false => self.counts.abandoned += 1,
                    }
                }
                // The server died or answered what does not validate: the caller asks again.
                Some(outcome) => {
                    tracing::warn!(topic = R::TOPIC.name(), ?outcome, "call not answered");
                    self.pending.swap_remove(i);
                    self.counts.abandoned += 1;
                }
            }
        }
        Ok(())
    }

    fn take(&mut self, payload: &[u8], attachment: Option<&[u8]>) {
        let req: R::Req = match self.wire.read(payload, attachment) {
            Ok(r) => r,
            Err(why) => return refused(&mut self.counts, R::TOPIC, &why),
        };
        self.counts.taken += 1;
        let (id, t_ns) = (req.meta().seq, req.meta().t_ns);
        // Asked again: the caller gave up the first attempt; so does this bridge. At the
        // in-flight limit the oldest goes (its caller has long asked again).
        let before = self.pending.len();
        self.pending.retain(|p| p.id != id);
        if self.pending.len() >= self.in_flight {
            self.pending.remove(0);
        }
        self.counts.abandoned += (before - self.pending.len()) as u64;
        match self.client.send(req, id, t_ns) {
            Ok(p) => self.pending.push(p),
            Err(e) => {
                tracing::warn!(topic = R::TOPIC.name(), "request not passed on: {e:#}");
                self.counts.abandoned += 1;
            }
        }
    }

    fn counts(&self) -> Counts {
        self.counts
    }

    fn busy(&self) -> bool {
        !self.pending.is_empty()
    }

    fn wire(&self) -> &Wire {
        &self.wire
    }

    fn wait_for_caller(&self, _: Duration) -> Result<()> {
        Ok(())
    }
}

fn refused(counts: &mut Counts, topic: TopicId, why: &str) {
    counts.refused += 1;
    if counts.refused == 1 || counts.refused.is_power_of_two() {
        tracing::warn!(
            topic = topic.name(),
            refused = counts.refused,
            "call refused off the wire: {why}"
        );
    }
}
