//! Accounting over real iceoryx2 shared memory (in one process, two nodes): malformed
//! messages from a peer are rejected and counted, overflowed samples are counted as drops, and
//! the invariant received + dropped == published holds.

use glint_runtime::ports::{Inbox, Outbox};
use glint_runtime::{open_node, remove_shm, shm_entries};
use shared_types::topics::{create_all, credit_window};
use shared_types::{DropReason, Message, Meta, Scenario, ServiceId, Spectrum, TopicId};

fn prefix(tag: &str) -> String {
    format!("glt{}{}_", std::process::id() % 100_000, tag)
}

/// A scenario with a small camera and no other section.
fn scenario() -> Scenario {
    let text = include_str!("../../../scenarios/debris-geo.toml")
        .replace("width_px = 1024", "width_px = 64")
        .replace("height_px = 1024", "height_px = 64");
    Scenario::from_toml_str(&text, "debris-geo.toml (64×64)").unwrap()
}

fn spectrum(k: u64) -> Spectrum {
    let mut s = Spectrum {
        n_bands: 1,
        sun_body: [1.0, 0.0, 0.0],
        observer_body: [0.0, 1.0, 0.0],
        range_m: 1.0,
        frame_index: k,
        ..Default::default()
    };
    s.wavelength_nm[0] = 650.0;
    s.flux_w[0] = 1.0 + k as f64;
    s
}

#[test]
fn malformed_messages_are_rejected_and_counted() {
    let p = prefix("m");
    {
        let node = open_node(&p, "test").unwrap();
        let _keep = create_all(&node, &scenario()).unwrap();
        let mut out = Outbox::open(&node, TopicId::Spectrum, ServiceId::Sensor).unwrap();
        let (mut inbox, _l) = Inbox::<Spectrum>::open(&node, TopicId::Spectrum).unwrap();

        out.send(spectrum(0), 0).unwrap();
        // A peer sends a message whose payload no longer matches its hash (corruption)…
        let mut bad = spectrum(1);
        bad.meta = Meta::new(1, 0, 0, ServiceId::Sensor);
        bad.seal();
        bad.flux_w[0] = f64::NAN;
        out.send_raw(bad).unwrap();
        // …and one from another contract version.
        let mut alien = spectrum(2);
        alien.meta = Meta::new(2, 0, 0, ServiceId::Sensor);
        alien.seal();
        alien.meta.contract_version = shared_types::CONTRACT_VERSION + 1;
        out.send_raw(alien).unwrap();
        out.send(spectrum(3), 0).unwrap();

        let mut seen = vec![];
        inbox
            .drain(|r| {
                seen.push(r.msg.frame_index);
                Ok(())
            })
            .unwrap();
        assert_eq!(seen, vec![0, 3]);
        assert_eq!(inbox.stats.received, 2);
        assert_eq!(inbox.stats.dropped[DropReason::Malformed as usize], 2);
        assert!(inbox.last_reject.is_some());
    }
    remove_shm(&p);
    assert!(shm_entries(&p).is_empty());
}

#[test]
fn overflow_is_counted_and_the_invariant_holds() {
    let p = prefix("o");
    {
        let node = open_node(&p, "test").unwrap();
        let _keep = create_all(&node, &scenario()).unwrap();
        let mut out = Outbox::open(&node, TopicId::Spectrum, ServiceId::Sensor).unwrap();
        let (mut inbox, _l) = Inbox::<Spectrum>::open(&node, TopicId::Spectrum).unwrap();
        // A consumer that does not keep up: 3 buffers' worth arrive before it reads.
        let n = 3 * credit_window(TopicId::Spectrum, &scenario()) as u64;
        for k in 0..n {
            out.send(spectrum(k), k).unwrap();
        }
        let mut last = None;
        inbox
            .drain(|r| {
                last = Some(r.msg.frame_index);
                Ok(())
            })
            .unwrap();
        assert_eq!(last, Some(n - 1), "safe overflow keeps the newest samples");
        let dropped = inbox.stats.dropped[DropReason::Overflow as usize];
        assert!(dropped > 0);
        assert_eq!(inbox.stats.received + dropped, n);
        assert_eq!(out.stats.published, n);
    }
    remove_shm(&p);
    assert!(shm_entries(&p).is_empty());
}
