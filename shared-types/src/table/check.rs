//! The table's rules, held by [`check`]: ids in their rows' order, names unique, every
//! producer listing its topics, every data input of a restartable service with a replay
//! source, the visitor and the pattern agreeing.

use super::*;

/// The table's own consistency, checked by a test and by `glint run` before it deploys: ids
/// in order, names unique, every data topic a restartable service consumes has a replay
/// source, every producer declares its topics, the visitor and the pattern agree.
pub fn check() -> Result<(), String> {
    check_rows(&TOPICS, &SERVICES)
}

pub(super) fn check_rows(topics: &[TopicSpec], services: &[ServiceSpec]) -> Result<(), String> {
    let service = |id: ServiceId| services.iter().find(|s| s.id == id);
    let topic = |id: TopicId| topics.iter().find(|t| t.id == id);
    for (i, s) in services.iter().enumerate() {
        if s.id as usize != i {
            return Err(format!("service row {i} holds {:?}", s.id));
        }
        for input in s.inputs {
            let Some(t) = topic(*input) else {
                return Err(format!(
                    "service {} consumes {input:?}, which has no row",
                    s.name
                ));
            };
            let restartable = s.id != ServiceId::Orchestrator;
            let replayed = matches!(t.replay, Replay::Remade | Replay::Logged);
            if restartable && !replayed {
                return Err(format!(
                    "service {} consumes `{}`, which has no replay source ({:?})",
                    s.name, t.name, t.replay
                ));
            }
            if !t.is_data() {
                return Err(format!(
                    "service {} lists `{}` as a data input",
                    s.name, t.name
                ));
            }
        }
        for output in s.outputs {
            if !topic(*output).is_some_and(|t| t.from == From::One(s.id)) {
                return Err(format!(
                    "service {} lists {output:?} as an output, which it does not produce",
                    s.name
                ));
            }
        }
    }
    for (i, t) in topics.iter().enumerate() {
        if t.id as usize != i {
            return Err(format!("topic row {i} holds {:?}", t.id));
        }
        if topics.iter().filter(|u| u.name == t.name).count() != 1 {
            return Err(format!("topic name `{}` is not unique", t.name));
        }
        if let From::One(p) = t.from {
            if !service(p).is_some_and(|s| s.outputs.contains(&t.id)) {
                return Err(format!(
                    "topic `{}` is produced by {p:?}, which does not list it among its outputs",
                    t.name
                ));
            }
        }
        if let Count::PerInput(input) = t.count {
            let declared =
                (t.producer().and_then(service)).is_some_and(|s| s.inputs.contains(&input));
            if !declared {
                return Err(format!(
                    "topic `{}` counts one per {input:?}, which its producer does not consume",
                    t.name
                ));
            }
        }
        // Every producer subscribes to the acks (its credit), a restarted one beside the
        // incarnation it replaces until that one's port is cleaned up.
        if let (true, Pattern::Messages { subscribers, .. }) = (t.id == TopicId::Ack, t.pattern) {
            let producers = services.iter().filter(|s| !s.outputs.is_empty()).count();
            if subscribers < producers + 1 {
                return Err(format!(
                    "topic `{}` takes {subscribers} subscribers; its {producers} producers \
                     and a restart need {}",
                    t.name,
                    producers + 1
                ));
            }
        }
        let frames = matches!(t.pattern, Pattern::Frames { .. });
        if frames != visit(t.id, IsFrames) {
            return Err(format!(
                "topic `{}`: its pattern and its payload type disagree",
                t.name
            ));
        }
    }
    Ok(())
}

struct IsFrames;

impl PayloadVisitor for IsFrames {
    type Out = bool;
    fn frames(self, _: &'static TopicSpec) -> bool {
        true
    }
    fn messages<T: Message>(self, _: &'static TopicSpec) -> bool {
        false
    }
    fn calls<Req: Message, Resp: Message>(self, _: &'static TopicSpec) -> bool {
        false
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_table_is_consistent() {
        check().unwrap();
        assert_eq!(TopicId::from_name("earth_frame"), Some(TopicId::EarthFrame));
        assert_eq!(ServiceId::from_name("tracker"), Some(ServiceId::Tracker));
        assert_eq!(ServiceId::from_u32(5), Some(ServiceId::Earth));
        assert_eq!(ServiceId::from_u32(6), Some(ServiceId::RelNav));
        assert_eq!(ServiceId::from_u32(7), Some(ServiceId::Photometry));
        assert_eq!(ServiceId::from_u32(8), Some(ServiceId::Bridge));
        assert_eq!(ServiceId::from_u32(9), None);
        assert_eq!(
            TopicId::from_name("photometry_estimate"),
            Some(TopicId::PhotometryEstimate)
        );
        assert_eq!(TopicId::from_name("relnav"), Some(TopicId::RelNav));
        assert_eq!(TopicId::from_u32(11), Some(TopicId::EarthAttitude));
        assert_eq!(payload_type_name(TopicId::Tracks), "glint.v8.Tracks");
        assert_eq!(
            payload_type_name(TopicId::EarthFrame),
            "glint.v8.FrameHeader"
        );
        assert_eq!(
            ServiceId::names(),
            "sensor, detector, tracker, inversion, earth, relnav, photometry, bridge"
        );
    }

    #[test]
    fn rows_that_break_the_rules_are_refused() {
        // A restartable service consuming a topic nobody can replay to it.
        let mut services = SERVICES;
        services[ServiceId::Earth as usize].inputs = &[TopicId::Tracks];
        let e = check_rows(&TOPICS, &services).unwrap_err();
        assert!(e.contains("no replay source"), "{e}");
        // A producer that does not declare its topic.
        let mut services = SERVICES;
        services[ServiceId::Detector as usize].outputs = &[];
        let e = check_rows(&TOPICS, &services).unwrap_err();
        assert!(e.contains("does not list it among its outputs"), "{e}");
        // Rows out of order.
        let mut topics = TOPICS;
        topics.swap(0, 1);
        let e = check_rows(&topics, &SERVICES).unwrap_err();
        assert!(e.contains("topic row 0"), "{e}");
        // A count per input its producer does not consume.
        let mut topics = TOPICS;
        topics[TopicId::Tracks as usize].count = Count::PerInput(TopicId::Frame);
        let e = check_rows(&topics, &SERVICES).unwrap_err();
        assert!(e.contains("does not consume"), "{e}");
        // Acks too few for every producer (five, with the earth service) and a restart.
        let mut topics = TOPICS;
        topics[TopicId::Ack as usize].pattern = Pattern::Messages {
            publishers: 16,
            subscribers: 4,
            buffer: 256,
            history: false,
        };
        let e = check_rows(&topics, &SERVICES).unwrap_err();
        assert!(e.contains("subscribers"), "{e}");
    }
}
