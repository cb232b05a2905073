//! What crosses hosts, from the table and the scenario's placement alone (so every host's
//! bridge derives the same routes without talking): a host *exports* a topic when one of its
//! services writes it and a service of another host reads it, and *imports* it when the
//! reverse holds.

use shared_types::scenario::Scenario;
use shared_types::table::{From, TOPICS};
use shared_types::{deployment, ServiceId, TopicId};

/// The services that read `topic` in `scenario`.
pub fn readers(scenario: &Scenario, topic: TopicId) -> Vec<ServiceId> {
    match topic {
        // Data topics: the consumers the table lists (the orchestrator's taps among them).
        TopicId::Frame
        | TopicId::Spectrum
        | TopicId::Truth
        | TopicId::Detections
        | TopicId::Tracks
        | TopicId::EarthFrame
        | TopicId::EarthAttitude
        | TopicId::Stereo
        | TopicId::RelNav
        | TopicId::Photometry
        | TopicId::PhotometryEstimate => deployment::consumers(scenario, topic),
        TopicId::Heartbeat => vec![ServiceId::Orchestrator],
        // Every service obeys control.
        TopicId::Control => deployment::services(scenario)
            .into_iter()
            .filter(|s| *s != ServiceId::Bridge)
            .collect(),
        // A producer reads its consumers' acks (its sim-clock credit).
        TopicId::Ack => {
            let mut producers: Vec<ServiceId> = (TOPICS.iter())
                .filter(|t| t.is_data() && deployment::carries(scenario, t.id))
                .filter_map(|t| t.producer())
                .collect();
            producers.sort_unstable();
            producers.dedup();
            producers
        }
        // Calls cross as calls ([`Routes::serves`], [`Routes::answers`]), not as topics.
        TopicId::Range | TopicId::Solve => vec![],
    }
}

/// The services that write `topic` in `scenario` (the bridge's own heartbeats stay home).
pub fn writers(scenario: &Scenario, topic: TopicId) -> Vec<ServiceId> {
    if !deployment::carries(scenario, topic) {
        return vec![];
    }
    match topic.spec().from {
        From::One(s) => vec![s],
        From::Every => std::iter::once(ServiceId::Orchestrator)
            .chain(deployment::services(scenario))
            .filter(|s| *s != ServiceId::Bridge)
            .collect(),
    }
}

/// The topics one host's bridge carries.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Routes {
    /// This host's name.
    pub host: String,
    /// Its index among the scenario's hosts, sorted by name ([`host_index`]).
    pub host_index: u16,
    /// Written here, read elsewhere: taken from iceoryx2, put on Zenoh.
    pub exports: Vec<TopicId>,
    /// Written elsewhere, read here: taken from Zenoh, published into iceoryx2.
    pub imports: Vec<TopicId>,
    /// Calls made here and answered on another host: the bridge is their server here, puts
    /// each request on Zenoh and answers with the response that comes back.
    pub serves: Vec<TopicId>,
    /// Calls made on another host and answered here: the bridge is their client here, asks
    /// the server each request that comes off Zenoh and puts its response back.
    pub answers: Vec<TopicId>,
}

/// `host`'s index among the scenario's hosts (sorted by name), as envelopes carry it.
pub fn host_index(scenario: &Scenario, host: &str) -> Option<u16> {
    scenario
        .hosts
        .keys()
        .position(|h| h == host)
        .map(|i| i as u16)
}

/// The routes of `host`'s bridge.
pub fn routes(scenario: &Scenario, host: &str) -> Routes {
    let on = |s: &ServiceId| scenario.host_of(*s) == Some(host);
    let mut exports = vec![];
    let mut imports = vec![];
    let (mut serves, mut answers) = (vec![], vec![]);
    for t in TopicId::ALL {
        let clients = deployment::callers(scenario, t);
        if let Some(server) = deployment::producer(t).filter(|_| !clients.is_empty()) {
            if clients.iter().any(on) && !on(&server) {
                serves.push(t);
            }
            if on(&server) && clients.iter().any(|s| !on(s)) {
                answers.push(t);
            }
        }
        let (w, r) = (writers(scenario, t), readers(scenario, t));
        if w.iter().any(on) && r.iter().any(|s| !on(s)) {
            exports.push(t);
        }
        if w.iter().any(|s| !on(s)) && r.iter().any(on) {
            imports.push(t);
        }
    }
    Routes {
        host: host.to_string(),
        host_index: host_index(scenario, host).unwrap_or(u16::MAX),
        exports,
        imports,
        serves,
        answers,
    }
}

/// Whether `host`'s bridge puts a message of `producer` on the wire: only what was written on
/// its own host (what it imported stays home, so nothing loops), never a bridge's.
pub fn exported_by(scenario: &Scenario, host: &str, producer: u32) -> bool {
    ServiceId::from_u32(producer)
        .is_some_and(|p| p != ServiceId::Bridge && scenario.host_of(p) == Some(host))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The paper's debris scene, sensor | detector + tracker, the laser as given.
    fn split(laser: bool) -> Result<Scenario, String> {
        use shared_types::scenario::{HostSpec, ServicePlacement};
        let text = include_str!("../../../scenarios/debris-geo.toml");
        let mut sc = Scenario::from_toml_str(text, "debris-geo.toml").unwrap();
        sc.camera.as_mut().unwrap().tracker.laser = laser;
        for (name, port, orchestrator) in [("a", 7501, true), ("b", 7502, false)] {
            let endpoint = format!("tcp/127.0.0.1:{port}");
            (sc.hosts).insert(
                name.into(),
                HostSpec {
                    endpoint,
                    orchestrator,
                },
            );
        }
        for s in ["detector", "tracker"] {
            let host = Some("b".to_string());
            (sc.services).insert(s.into(), ServicePlacement { host, cpu: None });
        }
        Scenario::from_toml_str(&sc.to_toml(), "split.toml").map_err(|e| e.to_string())
    }

    /// The debris chain split sensor | detector + tracker: frames go out, detections and tracks
    /// come back; control goes out, heartbeats come back, acks both ways; truth stays home.
    #[test]
    fn the_split_debris_chain_routes_what_each_side_reads() {
        let sc = split(false).unwrap();
        let a = routes(&sc, "a");
        let b = routes(&sc, "b");
        use TopicId::*;
        assert_eq!(a.exports, [Frame, Control, Ack]);
        assert_eq!(a.imports, [Heartbeat, Ack, Detections, Tracks]);
        assert_eq!(b.exports, [Heartbeat, Ack, Detections, Tracks]);
        assert_eq!(b.imports, [Frame, Control, Ack]);
        assert_eq!((a.host_index, b.host_index), (0, 1));
        // what a bridge imported never goes back
        assert!(exported_by(&sc, "a", ServiceId::Orchestrator as u32));
        assert!(!exported_by(&sc, "a", ServiceId::Detector as u32));
        assert!(exported_by(&sc, "b", ServiceId::Detector as u32));
        assert!(!exported_by(&sc, "b", ServiceId::Bridge as u32));
    }

    /// With the laser on, the tracker on `b` calls the sensor on `a` across hosts: `b`'s bridge
    /// serves the calls there, `a`'s asks the sensor.
    #[test]
    fn the_laser_across_hosts_is_served_by_one_bridge_and_answered_by_the_other() {
        let sc = split(true).unwrap();
        let (a, b) = (routes(&sc, "a"), routes(&sc, "b"));
        use TopicId::*;
        assert_eq!(
            (a.serves.as_slice(), a.answers.as_slice()),
            (&[][..], &[Range][..])
        );
        assert_eq!(
            (b.serves.as_slice(), b.answers.as_slice()),
            (&[Range][..], &[][..])
        );
        let off = split(false).unwrap();
        assert!(routes(&off, "a").answers.is_empty() && routes(&off, "b").serves.is_empty());
    }
}
