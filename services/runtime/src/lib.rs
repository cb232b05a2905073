//! Plumbing every glint service shares: the iceoryx2 node under a per-deployment prefix, typed
//! ports with per-message accounting, the WaitSet loop (deadline per input, tick), heartbeats,
//! control handling, and tracing setup.
//!
//! A service is a pure core plus a thin node loop; this crate is the loop's vocabulary.

pub mod checkpoint;
pub mod clock;
pub mod credit;
pub mod housekeeping;
pub mod lifeline;
mod loop_timer;
pub mod node;
pub mod placement;
pub mod ports;
pub mod rpc;
pub mod service;
pub mod stats;
pub mod tamper;
pub mod waitloop;

pub use clock::mono_ns;
pub use credit::{AckReader, Credit};
pub use housekeeping::Housekeeping;
pub use node::{
    glint_prefixes, init_tracing, is_deployment_prefix, leftovers, live_nodes, open_node,
    remove_shm, shm_entries,
};
pub use ports::{Inbox, Outbox};
pub use service::{run_service, Frame, Io, NoInput, Output, Service, ServiceArgs, Setup};
pub use stats::TopicStats;
pub use waitloop::{run_loop, Exit, Step, Wake};
