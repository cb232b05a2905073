//! `glint run --record`: every tapped topic in DIR/run.mcap, read back with the `mcap` crate
//! (a reader that knows nothing of glint's runtime). Every channel's message count equals the
//! report's `published`, and each topic's digest recomputed from the recorded bytes alone
//! equals the report's — so the bytes are the messages as they were in shared memory, frames'
//! pixels included (each frame's pixel checksum recomputed from its recorded pixels).

mod common;

use std::collections::BTreeMap;

use common::*;
use shared_types::table::{visit, PayloadVisitor, TopicSpec};
use shared_types::{FrameHeader, Message, TopicId};
use xxhash_rust::xxh3::Xxh3;

/// Folds one recorded message into its topic's digest, as the orchestrator's tap does.
struct Fold<'a> {
    bytes: &'a [u8],
    digest: &'a mut Xxh3,
}

impl PayloadVisitor for Fold<'_> {
    type Out = ();
    fn frames(self, _: &'static TopicSpec) {
        let n = std::mem::size_of::<FrameHeader>();
        let h: FrameHeader = bytemuck::pod_read_unaligned(&self.bytes[..n]);
        let pixels = &self.bytes[n..];
        assert_eq!(pixels.len(), 2 * (h.width_px * h.height_px) as usize);
        let px: Vec<u16> = pixels
            .chunks_exact(2)
            .map(|b| u16::from_le_bytes([b[0], b[1]]))
            .collect();
        assert_eq!(
            shared_types::pixels_xxh3(&px),
            h.pixels_xxh3,
            "frame {}",
            h.frame_index
        );
        self.digest.update(&h.meta.seq.to_le_bytes());
        self.digest.update(&h.pixels_xxh3.to_le_bytes());
    }
    fn messages<T: Message>(self, _: &'static TopicSpec) {
        assert_eq!(self.bytes.len(), std::mem::size_of::<T>());
        let m: T = bytemuck::pod_read_unaligned(self.bytes);
        m.fold_digest(self.digest);
    }
    fn calls<Req: Message, Resp: Message>(self, spec: &'static TopicSpec) {
        panic!("a call recorded: {}", spec.name);
    }
}

/// The offset of `meta.seq` in a channel's payload, from its schema's JSON only.
fn seq_offset(schema: &[u8]) -> usize {
    let v: serde_json::Value = serde_json::from_slice(schema).expect("the schema is JSON");
    let types = v["types"].as_array().expect("the schema's types");
    let field = |ty: &str, name: &str| {
        let t = types
            .iter()
            .find(|t| t["name"] == ty)
            .expect("a described type");
        let f = (t["fields"].as_array().unwrap().iter())
            .find(|f| f["name"] == name)
            .expect("a described field");
        (
            f["offset"].as_u64().unwrap() as usize,
            f["type"].as_str().unwrap().to_string(),
        )
    };
    let top = types[0]["name"].as_str().unwrap();
    assert_eq!(types[0]["contract_name"], v["type"]);
    let (meta_at, meta_ty) = field(top, "meta");
    assert_eq!(meta_ty, "Meta");
    let (seq_at, seq_ty) = field("Meta", "seq");
    assert_eq!(seq_ty, "u64");
    meta_at + seq_at
}

/// Runs `scenario` with `--record` and checks the recording against its report.
fn recorded_run_matches_its_report(scenario: &std::path::Path, dir: &std::path::Path) {
    let r = run_ok(Some(scenario), dir, &["--record"]);
    assert!(r.typed.results.success);
    let path = r.dir.join("run.mcap");
    let bytes = std::fs::read(&path).expect("run.mcap");
    let mut digests: BTreeMap<String, (u64, Xxh3)> = BTreeMap::new();
    let mut last_log_time: BTreeMap<String, u64> = BTreeMap::new();
    for m in mcap::MessageStream::new(&bytes).expect("an MCAP file") {
        let m = m.expect("a readable message");
        let topic = TopicId::from_name(&m.channel.topic).expect("a topic of the table");
        let schema = m.channel.schema.as_ref().expect("a schema");
        assert_eq!(
            schema.name,
            shared_types::table::payload_type_name(topic),
            "{}",
            m.channel.topic
        );
        assert_eq!(
            (
                schema.encoding.as_str(),
                m.channel.message_encoding.as_str()
            ),
            ("glint.repr-c", "glint.repr-c")
        );
        // the schema alone locates the header: `meta.seq` read at the offsets it gives
        let seq_at = seq_offset(&schema.data);
        let seq = u64::from_le_bytes(m.data[seq_at..seq_at + 8].try_into().unwrap());
        assert_eq!(seq as u32, m.sequence, "{}", m.channel.topic);
        // log time is the producer's send time: increasing per topic of one producer (the
        // heartbeats' many producers interleave)
        if topic != TopicId::Heartbeat {
            let last = last_log_time.entry(m.channel.topic.clone()).or_default();
            assert!(m.log_time >= *last);
            *last = m.log_time;
        }
        let (n, digest) = digests.entry(m.channel.topic.clone()).or_default();
        *n += 1;
        visit(
            topic,
            Fold {
                bytes: &m.data,
                digest,
            },
        );
    }
    let topics = &r.typed.results.topics;
    let tapped: Vec<&String> = topics
        .iter()
        .filter(|(_, t)| t.consumers.contains_key("orchestrator"))
        .map(|(n, _)| n)
        .collect();
    // the heartbeats ride along: every service's, read as glint's type
    let (beats, _) = digests.remove("heartbeat").expect("heartbeats recorded");
    assert!(beats > 0);
    assert_eq!(
        digests.keys().collect::<Vec<_>>(),
        tapped,
        "one channel per tapped topic"
    );
    for (name, (n, digest)) in &digests {
        let t = &topics[name];
        assert_eq!(Some(*n), t.published, "{name}");
        assert_eq!(
            Some(format!("{:016x}", digest.digest())),
            t.digest_xxh3,
            "{name}: the digest of the recorded bytes"
        );
    }
    let rec = r
        .typed
        .run
        .recording
        .as_ref()
        .expect("the report names the recording");
    assert!(
        rec.failure.is_none() && rec.not_written.is_empty(),
        "{rec:?}"
    );
    assert_eq!(
        rec.messages.values().sum::<u64>(),
        beats + digests.values().map(|d| d.0).sum::<u64>()
    );
    assert_eq!(rec.messages["heartbeat"], beats);
    // the scenario rides along as metadata
    let summary = mcap::Summary::read(&bytes).unwrap().expect("a summary");
    // the heartbeats' channel and the faults' (none injected: no message)
    assert_eq!(summary.channels.len(), digests.len() + 2);
    // the report rides along as an attachment, as written
    let index = (summary.attachment_indexes.iter())
        .find(|a| a.name == "report.json")
        .expect("the report attached");
    let attached = mcap::read::attachment(&bytes, index).unwrap();
    let attached: serde_json::Value = serde_json::from_slice(&attached.data).unwrap();
    assert_eq!(attached, read_json(&r.dir.join("report.json")));
    let meta = summary
        .metadata_indexes
        .iter()
        .find(|m| m.name == "scenario");
    assert!(meta.is_some(), "no scenario metadata");
}

#[test]
fn a_recorded_debris_run_holds_every_frame_and_message_as_the_report_counts_them() {
    let dir = temp_dir("record-debris");
    recorded_run_matches_its_report(&scenario("debris-geo.toml"), &dir.join("out"));
}

#[test]
fn a_recorded_photometry_run_holds_every_sample_and_estimate() {
    let dir = temp_dir("record-photometry");
    recorded_run_matches_its_report(&scenario("photometry-geo.toml"), &dir.join("out"));
}

/// Without `--record` no file is written and the report names no recording.
#[test]
fn a_run_without_record_writes_no_recording() {
    let dir = temp_dir("record-none");
    let r = run_ok(
        Some(&scenario("photometry-geo.toml")),
        &dir.join("out"),
        &[],
    );
    assert!(!r.dir.join("run.mcap").exists());
    assert!(r.typed.run.recording.is_none());
}
