//! glint-bridge: a deployment split across hosts (ADR 0038). The pure core says what crosses
//! ([`routes`]), how it is wrapped ([`envelope`]) and how a link's losses are counted
//! ([`link`]); the node (feature `node`) carries it between iceoryx2 and Zenoh.

pub mod envelope;
pub mod link;
#[cfg(feature = "node")]
pub mod node;
pub mod routes;
