//! A recording (`glint run --record`'s `run.mcap`) read back: the file mapped, every message
//! indexed by channel, the sensor's topics by sequence number, with the scenario and the report
//! the run stored in it. The replay's streams ([`crate::recorded`]) and `glint replay --inspect`
//! read it; nothing is copied out of the map until a message is published.

use std::collections::BTreeMap;
use std::ops::Range;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use shared_types::{FrameHeader, Meta, TopicId, Truth};

/// One channel of the file, as `--inspect` shows it.
#[derive(Debug, Clone, PartialEq)]
pub struct ChannelSummary {
    pub topic: String,
    pub schema: String,
    pub messages: u64,
    pub bytes: u64,
    /// Log times (the producers' send times) of the first and last message [ns].
    pub log_span_ns: (u64, u64),
    /// Publish times (simulated) of the first and last message [ns].
    pub sim_span_ns: (u64, u64),
}

/// A message's bytes: in the map (an uncompressed chunk), or decompressed.
#[derive(Debug)]
enum Bytes {
    Mapped(Range<usize>),
    Owned(Vec<u8>),
}

pub struct Recording {
    path: PathBuf,
    map: memmap2::Mmap,
    channels: BTreeMap<String, ChannelSummary>,
    /// Each of glint's topics (by its table name): message `k` at index `k`, its first copy.
    by_seq: BTreeMap<TopicId, Vec<Option<Bytes>>>,
    /// The resolved scenario (`scenario` metadata), TOML.
    pub scenario_toml: Option<String>,
    /// The run's `report.json` (attachment), if the run finished writing it.
    pub report_json: Option<String>,
}

/// The first 8 bytes of every message (its [`Meta`]'s `seq`).
fn seq_of(data: &[u8]) -> Option<u64> {
    Some(u64::from_le_bytes(data.get(..8)?.try_into().ok()?))
}

impl Recording {
    /// Maps and indexes `path`; an error names the file and what is wrong.
    pub fn open(path: &Path) -> Result<Recording> {
        let file =
            std::fs::File::open(path).with_context(|| format!("opening {}", path.display()))?;
        // SAFETY: the map is read-only; a recording is not written while it is replayed (a
        // file truncated under us would fault, as any reader of a changing file may).
        let map = unsafe { memmap2::Mmap::map(&file) }
            .with_context(|| format!("mapping {}", path.display()))?;
        let bad = |e: mcap::McapError| {
            anyhow::anyhow!("{}: not a readable MCAP file: {e}", path.display())
        };
        let mut channels: BTreeMap<String, ChannelSummary> = BTreeMap::new();
        let mut by_seq: BTreeMap<TopicId, Vec<Option<Bytes>>> = BTreeMap::new();
        let base = map.as_ptr() as usize;
        let mut stream = mcap::read::RawMessageStream::new(&map).map_err(bad)?;
        while let Some(m) = stream.next() {
            let m = m.map_err(bad)?;
            let Some(channel) = stream.get_channel(m.header.channel_id) else {
                bail!(
                    "{}: a message on unknown channel {}",
                    path.display(),
                    m.header.channel_id
                );
            };
            let len = m.data.len() as u64;
            let (log, sim) = (m.header.log_time, m.header.publish_time);
            let c = channels
                .entry(channel.topic.clone())
                .or_insert_with(|| ChannelSummary {
                    topic: channel.topic.clone(),
                    schema: channel
                        .schema
                        .as_ref()
                        .map(|s| s.name.clone())
                        .unwrap_or_default(),
                    messages: 0,
                    bytes: 0,
                    log_span_ns: (log, log),
                    sim_span_ns: (sim, sim),
                });
            c.messages += 1;
            c.bytes += len;
            c.log_span_ns = (c.log_span_ns.0.min(log), c.log_span_ns.1.max(log));
            c.sim_span_ns = (c.sim_span_ns.0.min(sim), c.sim_span_ns.1.max(sim));
            // Heartbeats come from every service, each with its own sequence: not indexed.
            let Some(topic) = TopicId::from_name(&channel.topic) else {
                continue;
            };
            if topic.spec().producer().is_none() {
                continue;
            }
            let Some(seq) = seq_of(&m.data) else {
                bail!(
                    "{}: a {} message of {len} bytes",
                    path.display(),
                    channel.topic
                );
            };
            let bytes = match m.data {
                std::borrow::Cow::Borrowed(b) => {
                    let start = b.as_ptr() as usize - base;
                    Bytes::Mapped(start..start + b.len())
                }
                std::borrow::Cow::Owned(v) => Bytes::Owned(v),
            };
            let all = by_seq.entry(topic).or_default();
            let Ok(k) = usize::try_from(seq) else {
                continue;
            };
            if k > all.len() + (1 << 24) {
                bail!(
                    "{}: {} message {seq} is far past the others",
                    path.display(),
                    channel.topic
                );
            }
            if all.len() <= k {
                all.resize_with(k + 1, || None);
            }
            // A message sent again to a restarted consumer is the same message: the first kept.
            all[k].get_or_insert(bytes);
        }
        let (mut scenario_toml, mut report_json) = (None, None);
        if let Some(summary) = mcap::Summary::read(&map).map_err(bad)? {
            for index in &summary.metadata_indexes {
                let meta = mcap::read::metadata(&map, index).map_err(bad)?;
                if meta.name == "scenario" {
                    scenario_toml = meta.metadata.get("toml").cloned();
                }
            }
            for index in &summary.attachment_indexes {
                let a = mcap::read::attachment(&map, index).map_err(bad)?;
                if a.name == "report.json" {
                    report_json = Some(String::from_utf8_lossy(&a.data).into_owned());
                }
            }
        }
        Ok(Recording {
            path: path.to_path_buf(),
            map,
            channels,
            by_seq,
            scenario_toml,
            report_json,
        })
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Every channel with a message, by topic name.
    pub fn channels(&self) -> impl Iterator<Item = &ChannelSummary> {
        self.channels.values()
    }

    fn bytes<'a>(&'a self, b: &'a Bytes) -> &'a [u8] {
        match b {
            Bytes::Mapped(r) => &self.map[r.clone()],
            Bytes::Owned(v) => v,
        }
    }

    /// Message `k` of `topic`, if the recording has it.
    pub fn message(&self, topic: TopicId, k: u64) -> Option<&[u8]> {
        let all = self.by_seq.get(&topic)?;
        let b = all.get(usize::try_from(k).ok()?)?.as_ref()?;
        Some(self.bytes(b))
    }

    /// Messages of `topic` with sequence numbers 0, 1, …, without a gap.
    pub fn messages(&self, topic: TopicId) -> Result<Vec<&[u8]>> {
        let n = self.by_seq.get(&topic).map_or(0, |v| v.len() as u64);
        self.first(topic, n)
    }

    /// Messages 0 … `n - 1` of `topic`; an error names the first one missing.
    pub fn first(&self, topic: TopicId, n: u64) -> Result<Vec<&[u8]>> {
        let all = self.by_seq.get(&topic).map_or(&[][..], |v| v.as_slice());
        (0..n)
            .map(|k| match all.get(k as usize) {
                Some(Some(b)) => Ok(self.bytes(b)),
                Some(None) => bail!(
                    "{}: message {k} of topic {} is missing (the recording has {} after it; \
                     a fault dropped it, or a realtime run lost it)",
                    self.path.display(),
                    topic.name(),
                    all.len() - k as usize - 1
                ),
                None => bail!(
                    "{}: holds {} of the {n} {} messages asked for",
                    self.path.display(),
                    all.len(),
                    topic.name()
                ),
            })
            .collect()
    }

    /// The messages of a fixed-size type `T` on `topic` (its first `n`, or all), each checked
    /// for its size.
    pub fn typed<T: bytemuck::AnyBitPattern>(
        &self,
        topic: TopicId,
        n: Option<u64>,
    ) -> Result<Vec<T>> {
        let messages = match n {
            Some(n) => self.first(topic, n)?,
            None => self.messages(topic)?,
        };
        messages
            .into_iter()
            .enumerate()
            .map(|(k, b)| {
                if b.len() != std::mem::size_of::<T>() {
                    bail!(
                        "{}: {} message {k} has {} bytes; its type has {}",
                        self.path.display(),
                        topic.name(),
                        b.len(),
                        std::mem::size_of::<T>()
                    );
                }
                Ok(bytemuck::pod_read_unaligned(b))
            })
            .collect()
    }

    /// The truths of kind `kind`, in the order the sensor sent them (message `k` of the
    /// stream whose truth is of that kind: the `k`-th).
    pub fn truths(&self, kind: u32) -> Result<Vec<Truth>> {
        Ok(self
            .typed::<Truth>(TopicId::Truth, None)?
            .into_iter()
            .filter(|t| t.kind == kind)
            .collect())
    }
}

/// A recorded frame split into its header and pixels; an error if the sizes disagree.
pub fn split_frame(data: &[u8]) -> Result<(FrameHeader, &[u8])> {
    let n = std::mem::size_of::<FrameHeader>();
    if data.len() < n {
        bail!(
            "a frame of {} bytes, shorter than its header ({n})",
            data.len()
        );
    }
    let header: FrameHeader = bytemuck::pod_read_unaligned(&data[..n]);
    let pixels = &data[n..];
    let px = header.width_px as usize * header.height_px as usize;
    if pixels.len() != 2 * px {
        bail!(
            "frame {}: {} pixel bytes for {}×{} pixels",
            header.meta.seq,
            pixels.len(),
            header.width_px,
            header.height_px
        );
    }
    Ok((header, pixels))
}

/// The [`Meta`] at the start of a recorded message.
pub fn meta_of(data: &[u8]) -> Option<Meta> {
    let n = std::mem::size_of::<Meta>();
    data.get(..n).map(bytemuck::pod_read_unaligned)
}
