//! The events of a session (presence, strokes, meshes): what the group-commit writer publishes
//! once the data they describe is committed, what replicas exchange by `NOTIFY`, and what the
//! history of a late joiner is made of. The data model only: delivering them is
//! [`crate::fanout`]'s job.

use penmesh::protocol::{
    ParticipantId, PeerJoined, PeerLeft, PeerMesh, PeerPlacement, PeerRetained, PeerSolid,
    PeerStrokeBegin, PeerStrokeDone, PointBatch, ServerMessage, StrokeId, StrokeRemoval, mesh_url,
    simplified_url,
};
use penmesh::{Brush, Placement, Sample, Solid};
use serde::{Deserialize, Serialize};
use uuid::Uuid;

/// Version of the `NOTIFY` payloads replicas exchange (a second protocol, between proxies):
/// bump it when [`SessionEvent`]'s JSON changes. 2: presence events name the connection.
/// 4: strokes taken back and brought back (`removed`, `restored`), names changed (`renamed`),
/// brushes with a colour, and the replica and connection that caused an event (`from`).
/// 5: placements (`placed`). 6: a placement carries its row's id (`placed.id`). 7: solids
/// (`solid`).
pub const NOTIFY_VERSION: u16 = 7;

/// Largest `NOTIFY` payload this proxy sends; PostgreSQL's limit is 8000 bytes.
pub const MAX_NOTIFY_BYTES: usize = 7800;

/// One event of a session.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SessionEvent {
    pub session: Uuid,
    #[serde(flatten)]
    pub kind: EventKind,
    /// The connection of this replica that caused the event, if any: the fan-out does not
    /// hand an event back to its own connection (whose client has it already, or has it in
    /// the answer to its request). Local to a replica: see `from`.
    #[serde(skip)]
    pub origin: Option<u64>,
    /// In a `NOTIFY` payload: the replica ([`crate::fanout::Fanout::tag`]) and connection that
    /// caused the event, so that the replica's own listener, which receives its own
    /// notifications, restores `origin` ([`SessionEvent::arrived`]); other replicas ignore it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub from: Option<(u64, u64)>,
}

/// What happened. Stroke events name the participant who began the stroke. Presence events
/// name the connection too: one participant may be on several at once (its reconnect can say
/// hello before the old connection's end is noticed), and is present while any of them is.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "event", rename_all = "snake_case")]
pub enum EventKind {
    Joined {
        participant: ParticipantId,
        connection: Uuid,
        name: String,
    },
    Left {
        participant: ParticipantId,
        connection: Uuid,
    },
    StrokeBegin {
        participant: ParticipantId,
        stroke: StrokeId,
        brush: Brush,
    },
    /// Retained samples `first..first + points.len()` of the simplified stroke.
    Retained {
        participant: ParticipantId,
        stroke: StrokeId,
        first: u64,
        points: Vec<Sample>,
    },
    StrokeDone {
        participant: ParticipantId,
        stroke: StrokeId,
        n_retained: u64,
    },
    /// A mesh was stored; `created_at` tells a replacement from a repeat.
    Mesh {
        participant: ParticipantId,
        stroke: StrokeId,
        created_at: i64,
    },
    /// A participant present chose another name.
    Renamed {
        participant: ParticipantId,
        name: String,
    },
    /// The stroke was taken back by `by` (its drawer).
    Removed {
        participant: ParticipantId,
        stroke: StrokeId,
        by: ParticipantId,
    },
    /// The stroke was brought back by `by`.
    Restored {
        participant: ParticipantId,
        stroke: StrokeId,
        by: ParticipantId,
    },
    /// The stroke's placement is now `placement` (set by its drawer `participant`, or the
    /// work plane it was begun on). `id` is its `stroke_placements` row's: the order of a
    /// stroke's placements (the current one has the highest), set by the writer when it
    /// inserts the row (0 until then).
    Placed {
        participant: ParticipantId,
        stroke: StrokeId,
        placement: Placement,
        id: i64,
    },
    /// The stroke's solid is now `solid` (set by its drawer `participant`, or the solid it
    /// was begun as).
    Solid {
        participant: ParticipantId,
        stroke: StrokeId,
        solid: Solid,
    },
}

impl SessionEvent {
    pub fn new(session: Uuid, kind: EventKind) -> SessionEvent {
        SessionEvent { session, kind, origin: None, from: None }
    }

    /// The event, caused by connection `origin` of this replica.
    pub fn from_connection(origin: u64, session: Uuid, kind: EventKind) -> SessionEvent {
        SessionEvent { session, kind, origin: Some(origin), from: None }
    }

    /// The event as notified by the replica tagged `replica`: its origin goes with it.
    pub fn to_notify(&self, replica: u64) -> SessionEvent {
        SessionEvent { from: self.origin.map(|connection| (replica, connection)), ..self.clone() }
    }

    /// The event as received by the replica tagged `replica`'s listener: its origin back when
    /// it caused it, none otherwise.
    pub fn arrived(self, replica: u64) -> SessionEvent {
        let origin = self.from.filter(|(r, _)| *r == replica).map(|(_, connection)| connection);
        SessionEvent { origin, from: None, ..self }
    }

    /// This event as JSON for a `NOTIFY` payload, in pieces of at most `max` bytes: a
    /// `Retained` event too large for one is split into consecutive ones.
    fn notify_json(&self, max: usize) -> Vec<String> {
        let json = serde_json::to_string(self).expect("events serialise");
        if json.len() <= max {
            return vec![json];
        }
        match &self.kind {
            EventKind::Retained { participant, stroke, first, points } if points.len() > 1 => {
                let half = points.len() / 2;
                let part = |first: u64, points: &[Sample]| {
                    SessionEvent::new(
                        self.session,
                        EventKind::Retained {
                            participant: *participant,
                            stroke: *stroke,
                            first,
                            points: points.to_vec(),
                        },
                    )
                };
                let mut out = part(*first, &points[..half]).notify_json(max);
                out.extend(part(first + half as u64, &points[half..]).notify_json(max));
                out
            }
            // Names are cut to 200 characters when they join: cannot happen.
            _ => vec![json],
        }
    }

    /// The `NOTIFY` payloads of `events`, in order: as many events as fit in each, under
    /// [`MAX_NOTIFY_BYTES`], as `{"v": NOTIFY_VERSION, "events": [...]}`. One notification per
    /// event cost PostgreSQL more than the rest of a commit (each is queued, and read by every
    /// listening replica, on its own).
    pub fn notify_payloads(events: &[SessionEvent]) -> Vec<String> {
        let head = format!("{{\"v\":{NOTIFY_VERSION},\"events\":[");
        let room = MAX_NOTIFY_BYTES - head.len() - 2;
        let mut payloads = Vec::new();
        let mut current = head.clone();
        for json in events.iter().flat_map(|event| event.notify_json(room)) {
            if current.len() > head.len() && current.len() + 1 + json.len() + 2 > MAX_NOTIFY_BYTES {
                current.push_str("]}");
                payloads.push(std::mem::replace(&mut current, head.clone()));
            }
            if current.len() > head.len() {
                current.push(',');
            }
            current.push_str(&json);
        }
        if current.len() > head.len() {
            current.push_str("]}");
            payloads.push(current);
        }
        payloads
    }

    /// Reads a `NOTIFY` payload: its events, in order. One of another version (a replica of
    /// another release, during a rolling upgrade) is refused, so that the listener resyncs its
    /// clients rather than misread it.
    pub fn from_payload(payload: &str) -> anyhow::Result<Vec<SessionEvent>> {
        #[derive(Deserialize)]
        struct Version {
            v: Option<u16>,
        }
        #[derive(Deserialize)]
        struct Payload {
            events: Vec<SessionEvent>,
        }
        let version = serde_json::from_str::<Version>(payload)?.v;
        anyhow::ensure!(
            version == Some(NOTIFY_VERSION),
            "payload version {version:?}, this replica reads {NOTIFY_VERSION}"
        );
        Ok(serde_json::from_str::<Payload>(payload)?.events)
    }

    /// The message that tells a client of this event.
    pub fn message(&self) -> ServerMessage {
        match &self.kind {
            EventKind::Joined { participant, name, .. } => ServerMessage::PeerJoined(PeerJoined {
                participant: *participant,
                name: name.clone(),
            }),
            EventKind::Left { participant, .. } => {
                ServerMessage::PeerLeft(PeerLeft { participant: *participant })
            }
            EventKind::StrokeBegin { participant, stroke, brush } => {
                ServerMessage::PeerStrokeBegin(PeerStrokeBegin {
                    participant: *participant,
                    stroke: *stroke,
                    brush: *brush,
                })
            }
            EventKind::Retained { participant, stroke, first, points } => {
                ServerMessage::PeerRetained(PeerRetained {
                    participant: *participant,
                    stroke: *stroke,
                    first: *first,
                    points: PointBatch(points.clone()),
                })
            }
            EventKind::StrokeDone { participant, stroke, n_retained } => {
                ServerMessage::PeerStrokeDone(PeerStrokeDone {
                    participant: *participant,
                    stroke: *stroke,
                    n_retained: *n_retained,
                    url: simplified_url(*stroke),
                })
            }
            EventKind::Mesh { participant, stroke, .. } => ServerMessage::PeerMesh(PeerMesh {
                participant: *participant,
                stroke: *stroke,
                url: mesh_url(*stroke),
            }),
            EventKind::Renamed { participant, name } => ServerMessage::PeerRenamed(PeerJoined {
                participant: *participant,
                name: name.clone(),
            }),
            EventKind::Removed { participant, stroke, by } => {
                ServerMessage::StrokeRemoved(StrokeRemoval {
                    participant: *participant,
                    stroke: *stroke,
                    by: *by,
                })
            }
            EventKind::Restored { participant, stroke, by } => {
                ServerMessage::StrokeRestored(StrokeRemoval {
                    participant: *participant,
                    stroke: *stroke,
                    by: *by,
                })
            }
            EventKind::Placed { participant, stroke, placement, .. } => {
                ServerMessage::PeerPlacement(PeerPlacement {
                    participant: *participant,
                    stroke: *stroke,
                    placement: *placement,
                })
            }
            EventKind::Solid { participant, stroke, solid } => {
                ServerMessage::PeerSolid(PeerSolid {
                    participant: *participant,
                    stroke: *stroke,
                    solid: *solid,
                })
            }
        }
    }

    /// The bytes of samples the event holds (what a subscriber's queue counts; the frames
    /// encoded from them are counted by each connection's outgoing queue).
    pub fn sample_bytes(&self) -> usize {
        match &self.kind {
            EventKind::Retained { points, .. } => std::mem::size_of_val(points.as_slice()),
            _ => 0,
        }
    }

    /// The stroke the event is about, if any.
    pub fn stroke(&self) -> Option<StrokeId> {
        match &self.kind {
            EventKind::Joined { .. } | EventKind::Left { .. } | EventKind::Renamed { .. } => None,
            EventKind::StrokeBegin { stroke, .. }
            | EventKind::Retained { stroke, .. }
            | EventKind::StrokeDone { stroke, .. }
            | EventKind::Mesh { stroke, .. }
            | EventKind::Removed { stroke, .. }
            | EventKind::Restored { stroke, .. }
            | EventKind::Placed { stroke, .. }
            | EventKind::Solid { stroke, .. } => Some(*stroke),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn retained(stroke: Uuid, first: u64, n: usize) -> SessionEvent {
        let points = (0..n).map(|i| Sample::new(i as f64, 0.0, i as f64, 0.5)).collect();
        SessionEvent::new(
            Uuid::nil(),
            EventKind::Retained { participant: Uuid::nil(), stroke, first, points },
        )
    }

    // NOTIFY payloads carry their version; another version (or none) is refused, not misread.
    #[test]
    fn notify_payloads_are_versioned() {
        let event = SessionEvent::new(
            Uuid::nil(),
            EventKind::StrokeDone { participant: Uuid::nil(), stroke: Uuid::nil(), n_retained: 3 },
        );
        let payload = SessionEvent::notify_payloads(std::slice::from_ref(&event)).remove(0);
        assert!(payload.contains(&format!("\"v\":{NOTIFY_VERSION}")), "{payload}");
        assert_eq!(SessionEvent::from_payload(&payload).unwrap(), vec![event.clone()]);
        let other = payload.replace(&format!("\"v\":{NOTIFY_VERSION}"), "\"v\":999");
        assert!(SessionEvent::from_payload(&other).unwrap_err().to_string().contains("999"));
        let unversioned = serde_json::to_string(&event).unwrap();
        assert!(SessionEvent::from_payload(&unversioned).is_err());
    }

    // A replica's own notifications come back to its listener with their origin, so that the
    // connection that caused an event is not handed it; another replica's carry none.
    #[test]
    fn an_event_comes_back_with_its_origin_only_to_the_replica_that_caused_it() {
        let kind =
            EventKind::StrokeDone { participant: Uuid::nil(), stroke: Uuid::nil(), n_retained: 3 };
        let event = SessionEvent::from_connection(42, Uuid::nil(), kind);
        let payload = SessionEvent::notify_payloads(&[event.to_notify(7)]).remove(0);
        let read = SessionEvent::from_payload(&payload).unwrap().remove(0);
        assert_eq!(read.clone().arrived(7), event, "back on the replica that caused it");
        assert_eq!(read.arrived(8).origin, None, "on another replica");
        let plain = SessionEvent::new(Uuid::nil(), event.kind.clone());
        let payload = SessionEvent::notify_payloads(&[plain.to_notify(7)]).remove(0);
        assert!(!payload.contains("from"), "{payload}");
    }

    #[test]
    fn large_retained_events_split_under_the_notify_limit() {
        let event = retained(Uuid::new_v4(), 10, 1000);
        let payloads = SessionEvent::notify_payloads(&[event]);
        assert!(payloads.len() > 1);
        let mut next = 10;
        for p in &payloads {
            assert!(p.len() <= MAX_NOTIFY_BYTES);
            for event in SessionEvent::from_payload(p).unwrap() {
                let EventKind::Retained { first, points, .. } = event.kind else { panic!() };
                assert_eq!(first, next);
                next += points.len() as u64;
            }
        }
        assert_eq!(next, 1010);
    }

    #[test]
    fn a_commits_events_share_notify_payloads_in_order() {
        let events: Vec<SessionEvent> =
            (0..300).map(|i| retained(Uuid::new_v4(), i, 1 + (i as usize % 7))).collect();
        let payloads = SessionEvent::notify_payloads(&events);
        assert!(payloads.len() < 20, "{} payloads for 300 small events", payloads.len());
        assert!(payloads.iter().all(|p| p.len() <= MAX_NOTIFY_BYTES));
        let read: Vec<SessionEvent> =
            payloads.iter().flat_map(|p| SessionEvent::from_payload(p).unwrap()).collect();
        assert_eq!(read, events);
        assert!(SessionEvent::notify_payloads(&[]).is_empty());
    }
}
