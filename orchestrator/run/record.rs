//! `glint run --record`: every data topic the orchestrator taps (the table's orchestrator row:
//! frames, spectra, truth, detections, tracks, Earth frames and attitudes, stereo epochs,
//! estimates, light-curve samples, and every topic a later service adds) and every service's
//! heartbeats, written to `DIR/run.mcap` as the orchestrator takes them. One channel per topic, its schema named by the
//! payload's contract type name (`glint.v8.Spectrum`), encoding `glint.repr-c`, its data the
//! type's layout (every field's name, offset, size and type, nested types too): the message's
//! bytes exactly as they were in shared memory (a frame: its `FrameHeader`, then its `u16`
//! pixels, little-endian). Log time is the producer's send time (`CLOCK_MONOTONIC` [ns]),
//! publish time the simulated time the message describes [ns]. The resolved scenario is the
//! file's `scenario` metadata, the run's `report.json` an attachment, and every injected fault
//! a JSON message on the `faults` channel (its log time the recording's start plus the fault's
//! `injected_s`). Chunked, uncompressed (frames do not compress worth the CPU).
//!
//! The recorder rides on the taps, which take every message anyway: it copies nothing but a
//! frame's header and pixels into one buffer for the writer. A write that fails stops the
//! recording, and the messages not written are counted, never silently missing.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use mcap::records::{MessageHeader, Metadata};
use serde::{Deserialize, Serialize};
use shared_types::messages::layout::layout_with_nested;
use shared_types::table::payload_type_name;
use shared_types::{deployment, FrameHeader, Message, Scenario, ServiceId, TopicId};

use crate::report::FaultReport;

/// The message encoding and schema encoding of every channel.
pub const ENCODING: &str = "glint.repr-c";

/// What a recording holds, for the run's report.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct RecordingReport {
    pub path: String,
    /// Messages written, per topic.
    pub messages: BTreeMap<String, u64>,
    /// Messages taken but not written (the recording failed at the first of them), per topic.
    pub not_written: BTreeMap<String, u64>,
    /// Why the recording stopped early, if it did.
    pub failure: Option<String>,
}

/// The schema's data: the payload's layout and every type its fields name, so that a reader
/// without glint decodes the bytes (`shared_types::messages::layout`).
fn schema_data(topic: TopicId) -> Vec<u8> {
    let frames = matches!(
        topic.spec().pattern,
        shared_types::table::Pattern::Frames { .. }
    );
    serde_json::json!({
        "type": payload_type_name(topic),
        "contract_version": shared_types::CONTRACT_VERSION,
        "repr": "C, little-endian, explicit padding",
        "frame": frames.then_some("the header, then width_px × height_px u16 pixels, row-major"),
        "types": layout_with_nested(payload_type_name(topic)),
    })
    .to_string()
    .into_bytes()
}

/// The channel of the injected faults (JSON, one [`FaultReport`] each).
pub const FAULTS_CHANNEL: &str = "faults";

/// Every message topic's payload type and every wire type's layout, as one JSON document
/// (`glint tool layouts`): what a client without a recording (the Python package's bundled
/// `glint_client/layouts/glint_v<N>.json`) decodes live messages with.
pub fn layouts_document() -> serde_json::Value {
    let topics: serde_json::Map<String, serde_json::Value> = (TopicId::ALL.iter())
        .filter(|t| !matches!(t.spec().pattern, shared_types::table::Pattern::Calls { .. }))
        .map(|t| (t.name().to_string(), payload_type_name(*t).into()))
        .collect();
    serde_json::json!({
        "about": "glint's wire-type layouts, as `glint run --record` writes them in each MCAP channel's schema; regenerate with `glint tool layouts`",
        "contract_version": shared_types::CONTRACT_VERSION,
        "topics": topics,
        "types": shared_types::messages::layout::layouts(),
    })
}

pub struct Recorder {
    path: PathBuf,
    /// `CLOCK_MONOTONIC` when it was opened [ns].
    started_mono_ns: u64,
    faults_channel: u16,
    writer: Option<mcap::Writer<BufWriter<File>>>,
    channels: BTreeMap<TopicId, u16>,
    written: BTreeMap<TopicId, u64>,
    not_written: BTreeMap<TopicId, u64>,
    failure: Option<String>,
    /// A frame's header and pixels, contiguous.
    buffer: Vec<u8>,
}

impl Recorder {
    /// Opens `path` with a channel for every topic the orchestrator taps in `scenario`.
    pub fn create(path: &Path, scenario: &Scenario) -> Result<Self> {
        let file = File::create(path).with_context(|| format!("creating {}", path.display()))?;
        let mut writer = mcap::WriteOptions::new()
            .compression(None)
            .profile("glint")
            .create(BufWriter::with_capacity(1 << 20, file))
            .with_context(|| format!("starting {}", path.display()))?;
        let mut channels = BTreeMap::new();
        let tapped = deployment::inputs(scenario, ServiceId::Orchestrator);
        for t in tapped.into_iter().chain([TopicId::Heartbeat]) {
            let schema = writer.add_schema(payload_type_name(t), ENCODING, &schema_data(t))?;
            let spec = t.spec();
            let metadata = BTreeMap::from([
                ("about".to_string(), spec.about.to_string()),
                (
                    "producer".to_string(),
                    spec.producer()
                        .map_or("every service", |p| p.name())
                        .to_string(),
                ),
            ]);
            channels.insert(
                t,
                writer.add_channel(schema, spec.name, ENCODING, &metadata)?,
            );
        }
        let fault_schema = writer.add_schema(
            "glint.FaultReport",
            "jsonschema",
            serde_json::to_string(&schemars::schema_for!(FaultReport))?.as_bytes(),
        )?;
        let faults_channel =
            writer.add_channel(fault_schema, FAULTS_CHANNEL, "json", &BTreeMap::new())?;
        writer.write_metadata(&Metadata {
            name: "scenario".to_string(),
            metadata: BTreeMap::from([
                ("name".to_string(), scenario.name.clone()),
                ("seed".to_string(), scenario.seed.to_string()),
                ("toml".to_string(), scenario.to_toml()),
            ]),
        })?;
        Ok(Recorder {
            path: path.to_path_buf(),
            started_mono_ns: glint_runtime::mono_ns(),
            faults_channel,
            writer: Some(writer),
            channels,
            written: BTreeMap::new(),
            not_written: BTreeMap::new(),
            failure: None,
            buffer: vec![],
        })
    }

    fn write(&mut self, topic: TopicId, meta: &shared_types::Meta, parts: &[&[u8]]) {
        let (Some(writer), Some(&channel_id)) = (self.writer.as_mut(), self.channels.get(&topic))
        else {
            *self.not_written.entry(topic).or_default() += 1;
            return;
        };
        let data: &[u8] = match parts {
            [one] => one,
            _ => {
                self.buffer.clear();
                for p in parts {
                    self.buffer.extend_from_slice(p);
                }
                &self.buffer
            }
        };
        let header = MessageHeader {
            channel_id,
            sequence: meta.seq as u32,
            log_time: meta.send_mono_ns,
            publish_time: meta.t_ns,
        };
        match writer.write_to_known_channel(&header, data) {
            Ok(()) => *self.written.entry(topic).or_default() += 1,
            Err(e) => {
                self.failure = Some(format!("writing {}: {e}", self.path.display()));
                self.writer = None;
                *self.not_written.entry(topic).or_default() += 1;
            }
        }
    }

    /// A message as it was in shared memory.
    pub fn message<T: Message>(&mut self, topic: TopicId, msg: &T) {
        self.write(topic, msg.meta(), &[bytemuck::bytes_of(msg)]);
    }

    /// A frame: its header, then its pixels.
    pub fn frame(&mut self, topic: TopicId, header: &FrameHeader, pixels: &[u16]) {
        let parts = [bytemuck::bytes_of(header), bytemuck::cast_slice(pixels)];
        self.write(topic, &header.meta, &parts);
    }

    /// What it holds so far.
    pub fn summary(&self) -> RecordingReport {
        let names = |m: &BTreeMap<TopicId, u64>| {
            m.iter()
                .map(|(t, n)| (t.name().to_string(), *n))
                .collect::<BTreeMap<_, _>>()
        };
        RecordingReport {
            path: self.path.display().to_string(),
            messages: names(&self.written),
            not_written: names(&self.not_written),
            failure: self.failure.clone(),
        }
    }

    /// Writes the run's faults and report, then closes the file (its summary and index);
    /// `None` if it closed cleanly, else why not.
    pub fn close(mut self, report_json: &str, faults: &[FaultReport]) -> Option<String> {
        let result = self.close_with(report_json, faults);
        result
            .err()
            .map(|e| format!("closing {}: {e}", self.path.display()))
    }

    fn close_with(&mut self, report_json: &str, faults: &[FaultReport]) -> Result<()> {
        let Some(mut w) = self.writer.take() else {
            return Ok(());
        };
        for (i, f) in faults.iter().enumerate() {
            let at_ns = (f.injected_s.unwrap_or(0.0) * 1e9).max(0.0) as u64;
            let header = MessageHeader {
                channel_id: self.faults_channel,
                sequence: i as u32,
                log_time: self.started_mono_ns + at_ns,
                publish_time: 0,
            };
            w.write_to_known_channel(&header, serde_json::to_string(f)?.as_bytes())?;
        }
        w.attach(&mcap::Attachment {
            log_time: glint_runtime::mono_ns(),
            create_time: glint_runtime::mono_ns(),
            name: "report.json".to_string(),
            media_type: "application/json".to_string(),
            data: std::borrow::Cow::Borrowed(report_json.as_bytes()),
        })?;
        w.finish()?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    /// The Python package's bundled layouts are this build's.
    #[test]
    fn the_python_package_bundles_these_layouts() {
        let bundled: serde_json::Value = serde_json::from_str(include_str!(
            "../../python/glint_client/layouts/glint_v8.json"
        ))
        .unwrap();
        assert_eq!(
            bundled,
            super::layouts_document(),
            "python/glint_client/layouts/glint_v8.json is stale: \
             `glint tool layouts > python/glint_client/layouts/glint_v8.json`"
        );
    }
}
