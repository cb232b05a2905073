//! glint's wire contract: the messages every service exchanges over iceoryx2 shared memory,
//! the table of services and topics (one place, so no two processes disagree), their QoS, and
//! the scenario schema.
//!
//! Only this crate and `glint-runtime` touch iceoryx2 directly.

pub mod config_error;
pub mod deployment;
pub mod input;
pub mod messages;
pub mod scenario;
pub mod table;
pub mod topics;

pub use config_error::ConfigError;
pub use messages::*;
pub use scenario::Scenario;
pub use table::{ServiceId, TopicId};

/// Version of the wire contract. Bump it on any change to a message layout or a topic's QoS:
/// it is part of every `#[type_name]` and of the `glint.contract` service attribute.
pub const CONTRACT_VERSION: u32 = 8;

/// xxh3-64 of a frame's pixels as little-endian bytes (the value in `FrameHeader::pixels_xxh3`).
pub fn pixels_xxh3(pixels: &[u16]) -> u64 {
    // On little-endian targets the byte view is the little-endian encoding; big-endian hosts are
    // rejected at compile time below.
    xxhash_rust::xxh3::xxh3_64(bytemuck::cast_slice(pixels))
}

#[cfg(target_endian = "big")]
compile_error!("glint's shared-memory contract is little-endian");
