//! The one event loop of every service: block in an iceoryx2 WaitSet on the input listeners
//! (each optionally with a deadline) and a periodic tick; never spin.
//!
//! Exit happens only on `TerminationRequest` (SIGTERM/SIGINT), on what [`crate::lifeline`]
//! reports (SIGHUP, a watched parent gone), or when the handler asks for it.
//! `Interrupt` is ignored on purpose: iceoryx2 raises it for SIGCONT too, and a service that is
//! SIGSTOPped and continued by fault injection must keep running (docs/iceoryx2 notes §9.1).

use std::time::Duration;

use anyhow::{anyhow, Result};
use iceoryx2::port::listener::Listener;
use iceoryx2::prelude::*;
use iceoryx2::waitset::WaitSetRunResult;
use shared_types::topics::Ipc;

/// Why the loop woke.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Wake {
    /// Input `i` (index into the listener list) has notifications.
    Input(usize),
    /// Input `i` produced nothing within its deadline.
    Missed(usize),
    /// The periodic tick.
    Tick,
    /// The handler's own timeout elapsed (it asked to be called back).
    Timeout,
}

/// What the handler wants next.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Step {
    /// Wait for the next event, but call back after at most this long.
    WaitAtMost(Duration),
    /// Wait for the next event (or the tick).
    Wait,
    /// Leave the loop.
    Stop,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Exit {
    /// The handler returned `Step::Stop`.
    Stopped,
    /// SIGTERM / SIGINT / SIGHUP, or the parent process ended.
    Terminated,
}

/// Runs the loop until the handler stops it or a termination signal arrives.
pub fn run_loop(
    inputs: &[(&Listener<Ipc>, Option<Duration>)],
    tick: Duration,
    mut handler: impl FnMut(&[Wake]) -> Result<Step>,
) -> Result<Exit> {
    crate::lifeline::handle_hangup();
    let waitset = WaitSetBuilder::new()
        .create::<Ipc>()
        .map_err(|e| anyhow!("waitset: {e:?}"))?;
    let mut guards = Vec::with_capacity(inputs.len());
    for (listener, deadline) in inputs {
        let g = match deadline {
            Some(d) => waitset.attach_deadline(*listener, *d),
            None => waitset.attach_notification(*listener),
        }
        .map_err(|e| anyhow!("waitset attach: {e:?}"))?;
        guards.push(g);
    }
    let tick_guard = waitset
        .attach_interval(tick)
        .map_err(|e| anyhow!("waitset tick: {e:?}"))?;
    let mut wakes: Vec<Wake> = Vec::with_capacity(inputs.len() + 2);
    // First call: let the handler do its startup work before waiting.
    let mut step = handler(&[Wake::Timeout])?;
    loop {
        let timeout = match step {
            Step::Stop => return Ok(Exit::Stopped),
            Step::Wait => tick,
            Step::WaitAtMost(d) => d.min(tick),
        };
        wakes.clear();
        let result = waitset
            .wait_and_process_once_with_timeout(
                |id| {
                    for (i, g) in guards.iter().enumerate() {
                        if id.has_event_from(g) {
                            wakes.push(Wake::Input(i));
                        } else if id.has_missed_deadline(g) {
                            wakes.push(Wake::Missed(i));
                        }
                    }
                    if id.has_event_from(&tick_guard) {
                        wakes.push(Wake::Tick);
                    }
                    CallbackProgression::Continue
                },
                timeout,
            )
            .map_err(|e| anyhow!("waitset wait: {e:?}"))?;
        if result == WaitSetRunResult::TerminationRequest {
            return Ok(Exit::Terminated);
        }
        if let Some(why) = crate::lifeline::end_requested() {
            tracing::info!("ending: {why}");
            return Ok(Exit::Terminated);
        }
        // Drain the notifications of inputs that fired, or the WaitSet fires again at once.
        for w in &wakes {
            if let Wake::Input(i) = w {
                inputs[*i]
                    .0
                    .try_wait(|_| {})
                    .map_err(|e| anyhow!("listener drain: {e:?}"))?;
            }
        }
        if wakes.is_empty() {
            wakes.push(Wake::Timeout);
        }
        step = handler(&wakes)?;
    }
}

/// Sleeps `d` outside the loop (a blocked call being retried); `false` when the process was
/// asked to end meanwhile (a termination signal, SIGHUP, its parent gone).
pub fn pause(node: &shared_types::topics::IpcNode, d: Duration) -> bool {
    // `Interrupt` is also raised by SIGCONT (see the module docs): not an end.
    let terminated = matches!(
        node.wait(d),
        Err(iceoryx2::node::NodeWaitFailure::TerminationRequest)
    );
    !terminated && crate::lifeline::end_requested().is_none()
}
