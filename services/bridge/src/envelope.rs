//! What travels beside each message on the wire: the Zenoh attachment of a put (ADR 0038).
//! The payload is the message's bytes as they sit in shared memory (a frame's header, then its
//! pixels); the envelope says what it is and where it stands in its link's sequence, so the
//! receiving bridge refuses what is not this contract's and counts what the link lost.

use shared_types::{TopicId, CONTRACT_VERSION};

/// `GLN2` in ASCII, little-endian: the first four bytes of every envelope; its last byte is
/// the envelope's own layout (2: `origin_host` u16 and `flags`), so a bridge of another layout
/// is refused (`Magic`) rather than misread.
pub const MAGIC: u32 = u32::from_le_bytes(*b"GLN2");

/// The 32 bytes of a Zenoh attachment.
#[derive(Debug, Clone, Copy, PartialEq, Eq, bytemuck::Pod, bytemuck::Zeroable)]
#[repr(C)]
pub struct Envelope {
    pub magic: u32,
    /// The sender's [`CONTRACT_VERSION`].
    pub contract_version: u32,
    /// [`TopicId`] as u32 (the key names it too; the two must agree).
    pub topic: u32,
    /// The sending bridge's host, as its index among the scenario's hosts (sorted by name).
    pub origin_host: u16,
    /// [`Envelope::RESENT`] or 0.
    pub flags: u16,
    /// Gap-free per (topic, origin host) from 0: a gap is what the link lost.
    pub link_seq: u64,
    /// xxh3 of the topic's payload type name and sizes ([`type_digest`]).
    pub type_digest: u64,
}

/// Size of an envelope on the wire [bytes].
pub const ENVELOPE_BYTES: usize = std::mem::size_of::<Envelope>();

/// Why a message off the wire is refused (each a counted `malformed` drop).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Refusal {
    /// No attachment, or not 32 bytes.
    NoEnvelope,
    /// The first four bytes are not [`MAGIC`].
    Magic,
    /// Another contract version (the sender is another glint).
    Contract(u32),
    /// The envelope's topic is not the key's.
    Topic,
    /// The payload type or size differs from this contract's.
    Type,
    /// The payload has not the size the topic's type gives.
    Size,
}

impl std::fmt::Display for Refusal {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Refusal::NoEnvelope => write!(f, "no 32-byte envelope"),
            Refusal::Magic => write!(f, "not a glint envelope"),
            Refusal::Contract(v) => {
                write!(
                    f,
                    "contract version {v}, this glint speaks {CONTRACT_VERSION}"
                )
            }
            Refusal::Topic => write!(f, "the envelope's topic is not the key's"),
            Refusal::Type => write!(f, "another payload type"),
            Refusal::Size => write!(f, "payload size differs from the topic's type"),
        }
    }
}

/// A fingerprint of what a topic carries: its payload type name, and the sizes of its header
/// and of one payload element; two bridges that agree on it lay the bytes out alike.
pub fn type_digest(topic: TopicId, header_bytes: usize, element_bytes: usize) -> u64 {
    let name = shared_types::table::payload_type_name(topic);
    digest_of(name, header_bytes, element_bytes)
}

/// The same fingerprint for a type named `name` (a call's request or response).
pub fn digest_of(name: &str, header_bytes: usize, element_bytes: usize) -> u64 {
    let mut bytes = name.as_bytes().to_vec();
    bytes.extend_from_slice(&(header_bytes as u64).to_le_bytes());
    bytes.extend_from_slice(&(element_bytes as u64).to_le_bytes());
    xxhash_rust::xxh3::xxh3_64(&bytes)
}

impl Envelope {
    /// A flag: this message was put on the wire before, and is put again because a host that
    /// left rejoined (what was in flight to its dead bridge); its consumers may have it.
    pub const RESENT: u16 = 1;

    pub fn new(topic: TopicId, origin_host: u16, link_seq: u64, type_digest: u64) -> Self {
        Envelope {
            magic: MAGIC,
            contract_version: CONTRACT_VERSION,
            topic: topic as u32,
            origin_host,
            flags: 0,
            link_seq,
            type_digest,
        }
    }

    /// The same envelope, marked [`Envelope::RESENT`].
    pub fn resent(self) -> Self {
        Envelope {
            flags: self.flags | Self::RESENT,
            ..self
        }
    }

    pub fn is_resent(&self) -> bool {
        self.flags & Self::RESENT != 0
    }

    pub fn to_bytes(&self) -> [u8; ENVELOPE_BYTES] {
        bytemuck::cast(*self)
    }

    /// The envelope of a message received under `topic`'s key, checked against what this
    /// bridge expects of the topic.
    pub fn read(
        attachment: Option<&[u8]>,
        topic: TopicId,
        type_digest: u64,
    ) -> Result<Envelope, Refusal> {
        let bytes = attachment.ok_or(Refusal::NoEnvelope)?;
        if bytes.len() != ENVELOPE_BYTES {
            return Err(Refusal::NoEnvelope);
        }
        let e: Envelope = bytemuck::pod_read_unaligned(bytes);
        if e.magic != MAGIC {
            return Err(Refusal::Magic);
        }
        if e.contract_version != CONTRACT_VERSION {
            return Err(Refusal::Contract(e.contract_version));
        }
        if e.topic != topic as u32 {
            return Err(Refusal::Topic);
        }
        if e.type_digest != type_digest {
            return Err(Refusal::Type);
        }
        Ok(e)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_envelope_reads_back_and_refuses_what_is_not_this_contracts() {
        let d = type_digest(TopicId::Frame, 64, 2);
        let e = Envelope::new(TopicId::Frame, 1, 41, d);
        let bytes = e.to_bytes();
        assert_eq!(Envelope::read(Some(&bytes), TopicId::Frame, d), Ok(e));
        let again = Envelope::read(Some(&e.resent().to_bytes()), TopicId::Frame, d).unwrap();
        assert!(again.is_resent() && !e.is_resent());
        assert_eq!((again.origin_host, again.link_seq), (1, 41));
        assert_eq!(
            Envelope::read(Some(&bytes[..31]), TopicId::Frame, d),
            Err(Refusal::NoEnvelope)
        );
        assert_eq!(
            Envelope::read(Some(&bytes), TopicId::Tracks, d),
            Err(Refusal::Topic)
        );
        let other = type_digest(TopicId::Frame, 64, 4);
        assert_ne!(d, other);
        assert_eq!(
            Envelope::read(Some(&bytes), TopicId::Frame, other),
            Err(Refusal::Type)
        );
        let mut old = e;
        old.contract_version = CONTRACT_VERSION - 1;
        assert_eq!(
            Envelope::read(Some(&old.to_bytes()), TopicId::Frame, d),
            Err(Refusal::Contract(CONTRACT_VERSION - 1))
        );
        let mut bad = bytes;
        bad[0] ^= 1;
        assert_eq!(
            Envelope::read(Some(&bad), TopicId::Frame, d),
            Err(Refusal::Magic)
        );
    }
}
