//! The Foxglove WebSocket protocol, the part a viewer needs (its specification is in the
//! github.com/foxglove/ws-protocol repository): the subprotocol, the server's JSON
//! messages (`serverInfo`, `advertise`, `status`), the binary `messageData` frame, and the
//! client's `subscribe` and `unsubscribe`, parsed defensively: nothing a client sends can
//! make the bridge panic.

use serde_json::{Value as Json, json};
use std::collections::BTreeMap;

/// The subprotocols the bridge speaks, the same protocol under two names: Foxglove's app
/// and the `foxglove` SDKs say `foxglove.sdk.v1`; Lichtblick, PlotJuggler's Foxglove bridge
/// client and npm's `@foxglove/ws-protocol` `FoxgloveClient` say `foxglove.websocket.v1`.
pub const SUBPROTOCOLS: [&str; 2] = ["foxglove.websocket.v1", "foxglove.sdk.v1"];

/// The binary opcode of a `messageData` frame (server to client).
pub const MESSAGE_DATA: u8 = 0x01;

/// The subprotocol to answer with: the first one the client offers that the bridge speaks.
/// `offered` holds the values of the request's `Sec-WebSocket-Protocol` headers, each a
/// comma-separated list.
pub fn choose_subprotocol<'a>(offered: impl IntoIterator<Item = &'a str>) -> Option<&'static str> {
    offered
        .into_iter()
        .flat_map(|v| v.split(','))
        .map(str::trim)
        .find_map(|p| SUBPROTOCOLS.iter().copied().find(|ours| *ours == p))
}

/// One advertised channel.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ChannelInfo {
    /// Its id (the bridge's channels are 1, 2, 3...).
    pub id: u32,
    /// The topic.
    pub topic: &'static str,
    /// The schema's name (`eqtrack_msgs/msg/<Name>`).
    pub schema_name: &'static str,
    /// The schema text (a ROS 2 `.msg` definition).
    pub schema: String,
}

/// A `status` message's level.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Level {
    /// 0.
    Info,
    /// 1.
    Warning,
    /// 2.
    Error,
}

/// The `serverInfo` message: `name`, no capabilities (the bridge only publishes), no client
/// encodings, `metadata` and `session_id`.
pub fn server_info(name: &str, metadata: &BTreeMap<String, String>, session_id: &str) -> String {
    json!({
        "op": "serverInfo",
        "name": name,
        "capabilities": [],
        "supportedEncodings": [],
        "metadata": metadata,
        "sessionId": session_id,
    })
    .to_string()
}

/// The `advertise` message of `channels`: CDR messages, `ros2msg` schemas.
pub fn advertise(channels: &[ChannelInfo]) -> String {
    let list: Vec<Json> = channels
        .iter()
        .map(|c| {
            json!({
                "id": c.id,
                "topic": c.topic,
                "encoding": "cdr",
                "schemaName": c.schema_name,
                "schema": c.schema,
                "schemaEncoding": "ros2msg",
            })
        })
        .collect();
    json!({"op": "advertise", "channels": list}).to_string()
}

/// A `status` message.
pub fn status(level: Level, message: &str) -> String {
    let level = match level {
        Level::Info => 0,
        Level::Warning => 1,
        Level::Error => 2,
    };
    json!({"op": "status", "level": level, "message": message}).to_string()
}

/// A `messageData` frame: opcode 0x01, the subscription id (u32 LE), the time (u64 LE, ns),
/// the payload.
pub fn message_data(subscription: u32, log_time: u64, payload: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(13 + payload.len());
    out.push(MESSAGE_DATA);
    out.extend_from_slice(&subscription.to_le_bytes());
    out.extend_from_slice(&log_time.to_le_bytes());
    out.extend_from_slice(payload);
    out
}

/// One entry of a `subscribe`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Subscription {
    /// The id the client chose.
    pub id: u32,
    /// The advertised channel.
    pub channel_id: u32,
}

/// What a client's text message asks.
#[derive(Debug, Clone, PartialEq)]
pub enum ClientOp {
    /// `subscribe`: the well-formed entries, and what is wrong with the others.
    Subscribe {
        /// Entries with integer `id` and `channelId` in the u32 range.
        ok: Vec<Subscription>,
        /// One [`Refusal::BadSubscription`] per malformed entry.
        bad: Vec<Refusal>,
    },
    /// `unsubscribe`: the well-formed ids, and what is wrong with the others.
    Unsubscribe {
        /// Integer ids in the u32 range.
        ok: Vec<u32>,
        /// One [`Refusal::BadSubscriptionId`] per malformed id.
        bad: Vec<Refusal>,
    },
    /// Any other `op` (the bridge declares no capability, so it supports none), cut to 64
    /// characters.
    Other(String),
}

/// Why a client's text message means nothing.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ParseError {
    /// Not JSON (serde_json's message: a syntax error, nesting deeper than 128, ...).
    NotJson(String),
    /// JSON, but not an object with a string `op`.
    NoOp,
    /// A `subscribe` without a `subscriptions` array, or an `unsubscribe` without a
    /// `subscriptionIds` array.
    NoList(&'static str),
}

impl std::fmt::Display for ParseError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ParseError::NotJson(e) => write!(f, "not JSON ({e})"),
            ParseError::NoOp => f.write_str("not a JSON object with a string `op`"),
            ParseError::NoList(what) => write!(f, "no `{what}` array"),
        }
    }
}

impl std::error::Error for ParseError {}

/// What the bridge refuses of a client's message, one part each; its text is what the
/// client is told (in an error `status` message), its [`kind`](Refusal::kind) a name.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Refusal {
    /// The text message means nothing.
    Unreadable(ParseError),
    /// Entry `index` of a `subscribe` has no integer `id` and `channelId` in the u32 range.
    BadSubscription {
        /// Its place in `subscriptions`.
        index: usize,
    },
    /// Entry `index` of an `unsubscribe` is not an integer in the u32 range.
    BadSubscriptionId {
        /// Its place in `subscriptionIds`.
        index: usize,
    },
    /// Subscription `id` names a channel that was not advertised.
    UnknownChannel {
        /// The subscription id.
        id: u32,
        /// The channel it names.
        channel_id: u32,
    },
    /// Subscription id `id` is in use.
    IdInUse {
        /// The subscription id.
        id: u32,
    },
    /// Channel `channel_id` is already subscribed, as `existing` (one subscription per
    /// channel).
    ChannelTaken {
        /// The subscription id asked for.
        id: u32,
        /// The channel.
        channel_id: u32,
        /// Its subscription.
        existing: u32,
    },
    /// `unsubscribe` of an id that is not subscribed.
    NotSubscribed {
        /// The id.
        id: u32,
    },
    /// An `op` the bridge does not support (at most 64 characters of it).
    Unsupported {
        /// The op.
        op: String,
    },
    /// A binary message (the bridge takes none: no `clientPublish`, no services).
    Binary,
}

impl Refusal {
    /// The refusal's name: `NotJson`, `NoOp`, `NoList`, `BadSubscription`,
    /// `BadSubscriptionId`, `UnknownChannel`, `IdInUse`, `ChannelTaken`, `NotSubscribed`,
    /// `Unsupported` or `Binary`.
    pub fn kind(&self) -> &'static str {
        match self {
            Refusal::Unreadable(ParseError::NotJson(_)) => "NotJson",
            Refusal::Unreadable(ParseError::NoOp) => "NoOp",
            Refusal::Unreadable(ParseError::NoList(_)) => "NoList",
            Refusal::BadSubscription { .. } => "BadSubscription",
            Refusal::BadSubscriptionId { .. } => "BadSubscriptionId",
            Refusal::UnknownChannel { .. } => "UnknownChannel",
            Refusal::IdInUse { .. } => "IdInUse",
            Refusal::ChannelTaken { .. } => "ChannelTaken",
            Refusal::NotSubscribed { .. } => "NotSubscribed",
            Refusal::Unsupported { .. } => "Unsupported",
            Refusal::Binary => "Binary",
        }
    }
}

impl std::fmt::Display for Refusal {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Refusal::Unreadable(e) => write!(f, "cannot read a client message: {e}"),
            Refusal::BadSubscription { index } => write!(
                f,
                "subscription {index}: `id` and `channelId` must be integers from 0 to 4294967295"
            ),
            Refusal::BadSubscriptionId { index } => write!(
                f,
                "subscription id {index}: must be an integer from 0 to 4294967295"
            ),
            Refusal::UnknownChannel { id, channel_id } => write!(
                f,
                "subscription {id}: no channel {channel_id} was advertised"
            ),
            Refusal::IdInUse { id } => write!(
                f,
                "subscription {id}: the id is in use (unsubscribe it first)"
            ),
            Refusal::ChannelTaken {
                id,
                channel_id,
                existing,
            } => write!(
                f,
                "subscription {id}: channel {channel_id} is already subscribed as {existing}"
            ),
            Refusal::NotSubscribed { id } => write!(f, "subscription {id}: not subscribed"),
            Refusal::Unsupported { op } => write!(
                f,
                "op `{op}` is not supported by eqtrack-live (it only publishes)"
            ),
            Refusal::Binary => f.write_str(
                "eqtrack-live takes no binary messages (it does not offer clientPublish or services)",
            ),
        }
    }
}

impl std::error::Error for Refusal {}

/// A JSON number that is an integer in the u32 range.
fn as_u32(v: Option<&Json>) -> Option<u32> {
    v.and_then(Json::as_u64).and_then(|x| u32::try_from(x).ok())
}

/// Parses a client's text message.
pub fn parse_client_message(text: &str) -> Result<ClientOp, ParseError> {
    let v: Json = serde_json::from_str(text).map_err(|e| ParseError::NotJson(e.to_string()))?;
    let op = v.get("op").and_then(Json::as_str).ok_or(ParseError::NoOp)?;
    match op {
        "subscribe" => {
            let list = v
                .get("subscriptions")
                .and_then(Json::as_array)
                .ok_or(ParseError::NoList("subscriptions"))?;
            let (mut ok, mut bad) = (Vec::new(), Vec::new());
            for (i, s) in list.iter().enumerate() {
                match (as_u32(s.get("id")), as_u32(s.get("channelId"))) {
                    (Some(id), Some(channel_id)) => ok.push(Subscription { id, channel_id }),
                    _ => bad.push(Refusal::BadSubscription { index: i }),
                }
            }
            Ok(ClientOp::Subscribe { ok, bad })
        }
        "unsubscribe" => {
            let list = v
                .get("subscriptionIds")
                .and_then(Json::as_array)
                .ok_or(ParseError::NoList("subscriptionIds"))?;
            let (mut ok, mut bad) = (Vec::new(), Vec::new());
            for (i, s) in list.iter().enumerate() {
                match as_u32(Some(s)) {
                    Some(id) => ok.push(id),
                    None => bad.push(Refusal::BadSubscriptionId { index: i }),
                }
            }
            Ok(ClientOp::Unsubscribe { ok, bad })
        }
        other => Ok(ClientOp::Other(other.chars().take(64).collect())),
    }
}

/// One client's subscriptions: subscription id → channel, at most one per channel (the
/// protocol's rule), ids unique among the active ones.
#[derive(Debug, Clone, Default)]
pub struct Subscriptions {
    by_id: BTreeMap<u32, u32>,
}

impl Subscriptions {
    /// None.
    pub fn new() -> Subscriptions {
        Subscriptions::default()
    }

    /// Adds `subs`; `known` says which channel ids were advertised. Returns one refusal per
    /// entry refused (an unknown channel, an id in use, a channel already subscribed); the
    /// others are taken.
    pub fn subscribe(
        &mut self,
        subs: &[Subscription],
        known: impl Fn(u32) -> bool,
    ) -> Vec<Refusal> {
        let mut refused = Vec::new();
        for s in subs {
            if !known(s.channel_id) {
                refused.push(Refusal::UnknownChannel {
                    id: s.id,
                    channel_id: s.channel_id,
                });
            } else if self.by_id.contains_key(&s.id) {
                refused.push(Refusal::IdInUse { id: s.id });
            } else if let Some(existing) = self.subscription_of(s.channel_id) {
                refused.push(Refusal::ChannelTaken {
                    id: s.id,
                    channel_id: s.channel_id,
                    existing,
                });
            } else {
                self.by_id.insert(s.id, s.channel_id);
            }
        }
        refused
    }

    /// Removes `ids`; returns one refusal per id that was not subscribed.
    pub fn unsubscribe(&mut self, ids: &[u32]) -> Vec<Refusal> {
        ids.iter()
            .filter(|id| self.by_id.remove(id).is_none())
            .map(|&id| Refusal::NotSubscribed { id })
            .collect()
    }

    /// The active subscriptions, by id.
    pub fn iter(&self) -> impl Iterator<Item = Subscription> + '_ {
        self.by_id
            .iter()
            .map(|(&id, &channel_id)| Subscription { id, channel_id })
    }

    /// The subscription id of channel `channel_id`, if it is subscribed.
    pub fn subscription_of(&self, channel_id: u32) -> Option<u32> {
        self.by_id
            .iter()
            .find(|(_, c)| **c == channel_id)
            .map(|(id, _)| *id)
    }

    /// The subscribed channels as a bit mask (bit `id` for channel `id` < 32).
    pub fn mask(&self) -> u32 {
        self.by_id
            .values()
            .filter(|c| **c < 32)
            .fold(0, |m, c| m | 1 << c)
    }

    /// How many subscriptions are active.
    pub fn len(&self) -> usize {
        self.by_id.len()
    }

    /// Whether none is.
    pub fn is_empty(&self) -> bool {
        self.by_id.is_empty()
    }
}

/// A client message as a session reads it from its WebSocket.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Incoming<'a> {
    /// A text message (valid UTF-8: the WebSocket library refuses others).
    Text(&'a str),
    /// A binary message.
    Binary(&'a [u8]),
}

/// What a session does with one client message.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Answer {
    /// What was refused, in order (empty: all of it was taken).
    pub refusals: Vec<Refusal>,
    /// The text message sent back: an error `status` naming the first [`SHOWN_REFUSALS`]
    /// refusals; `None` when nothing was refused.
    pub reply: Option<String>,
}

/// At most this many refusals are named in one `status` answer.
pub const SHOWN_REFUSALS: usize = 8;

/// A client session's subscriptions and how it answers its client's messages: `subscribe`
/// and `unsubscribe` change the subscriptions; anything else (an unknown op, text that is not
/// JSON, a subscription to a channel that was not advertised, an id in use, a binary
/// message) is refused, answered with an error `status` message and otherwise ignored.
#[derive(Debug, Clone)]
pub struct SessionState {
    subs: Subscriptions,
    /// The advertised channel ids.
    advertised: Vec<u32>,
}

impl SessionState {
    /// A session with no subscription, over the advertised `channels`.
    pub fn new(channels: &[ChannelInfo]) -> SessionState {
        SessionState {
            subs: Subscriptions::new(),
            advertised: channels.iter().map(|c| c.id).collect(),
        }
    }

    /// Its subscriptions.
    pub fn subscriptions(&self) -> &Subscriptions {
        &self.subs
    }

    /// Whether channel `channel_id` was advertised.
    pub fn advertised(&self, channel_id: u32) -> bool {
        self.advertised.contains(&channel_id)
    }

    /// Takes one client message: changes the subscriptions as it asks, and says what was
    /// refused and what to answer.
    pub fn handle(&mut self, msg: Incoming<'_>) -> Answer {
        let refusals = match msg {
            Incoming::Binary(_) => vec![Refusal::Binary],
            Incoming::Text(text) => match parse_client_message(text) {
                Ok(ClientOp::Subscribe { ok, mut bad }) => {
                    let advertised = &self.advertised;
                    bad.extend(self.subs.subscribe(&ok, |c| advertised.contains(&c)));
                    bad
                }
                Ok(ClientOp::Unsubscribe { ok, mut bad }) => {
                    bad.extend(self.subs.unsubscribe(&ok));
                    bad
                }
                Ok(ClientOp::Other(op)) => vec![Refusal::Unsupported { op }],
                Err(e) => vec![Refusal::Unreadable(e)],
            },
        };
        let reply = (!refusals.is_empty()).then(|| {
            let shown: Vec<String> = refusals
                .iter()
                .take(SHOWN_REFUSALS)
                .map(ToString::to_string)
                .collect();
            status(Level::Error, &shown.join("; "))
        });
        Answer { refusals, reply }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn a_message_data_frame_is_opcode_subscription_time_payload() {
        let f = message_data(0x0102_0304, 0x1122_3344_5566_7788, &[9, 8, 7]);
        assert_eq!(
            f,
            [
                0x01, 0x04, 0x03, 0x02, 0x01, 0x88, 0x77, 0x66, 0x55, 0x44, 0x33, 0x22, 0x11, 9, 8,
                7
            ]
        );
        assert_eq!(message_data(7, 0, &[]).len(), 13);
    }

    #[test]
    fn advertise_names_each_channel_with_cdr_and_ros2msg() {
        let text = advertise(&[ChannelInfo {
            id: 1,
            topic: "/eqtrack/state",
            schema_name: "eqtrack_msgs/msg/State",
            schema: "uint64 cycle\n".to_owned(),
        }]);
        let v: Json = serde_json::from_str(&text).unwrap();
        assert_eq!(v["op"], "advertise");
        let c = &v["channels"][0];
        assert_eq!(c["id"], 1);
        assert_eq!(c["topic"], "/eqtrack/state");
        assert_eq!(c["encoding"], "cdr");
        assert_eq!(c["schemaName"], "eqtrack_msgs/msg/State");
        assert_eq!(c["schemaEncoding"], "ros2msg");
        assert_eq!(c["schema"], "uint64 cycle\n");
        assert_eq!(v["channels"].as_array().unwrap().len(), 1);
    }

    #[test]
    fn server_info_and_status_are_the_specs_json() {
        let mut meta = BTreeMap::new();
        meta.insert("run".to_owned(), "demo".to_owned());
        let v: Json = serde_json::from_str(&server_info("eqtrack-live", &meta, "42")).unwrap();
        assert_eq!(v["op"], "serverInfo");
        assert_eq!(v["capabilities"], json!([]));
        assert_eq!(v["supportedEncodings"], json!([]));
        assert_eq!(v["metadata"]["run"], "demo");
        assert_eq!(v["sessionId"], "42");
        let s: Json = serde_json::from_str(&status(Level::Warning, "slow \"client\"")).unwrap();
        assert_eq!(
            s,
            json!({"op": "status", "level": 1, "message": "slow \"client\""})
        );
    }

    #[test]
    fn both_subprotocols_are_accepted_and_nothing_else() {
        assert_eq!(
            choose_subprotocol(["foxglove.websocket.v1"]),
            Some("foxglove.websocket.v1")
        );
        assert_eq!(
            choose_subprotocol(["foxglove.sdk.v1"]),
            Some("foxglove.sdk.v1")
        );
        // the client's order decides, across a list and several headers
        assert_eq!(
            choose_subprotocol(["chat, foxglove.sdk.v1 ,foxglove.websocket.v1"]),
            Some("foxglove.sdk.v1")
        );
        assert_eq!(
            choose_subprotocol(["x", "foxglove.websocket.v1"]),
            Some("foxglove.websocket.v1")
        );
        assert_eq!(
            choose_subprotocol(["foxglove.websocket.v2", "FOXGLOVE.SDK.V1"]),
            None
        );
        assert_eq!(choose_subprotocol(Vec::<&str>::new()), None);
    }

    #[test]
    fn subscribe_parses_good_entries_and_names_the_bad_ones() {
        let op = parse_client_message(
            r#"{"op":"subscribe","subscriptions":[{"id":0,"channelId":1},{"id":1.5,"channelId":2},{"id":"3","channelId":3},{"id":-1,"channelId":1},{"id":4294967296,"channelId":1},{"id":7}]}"#,
        )
        .unwrap();
        let ClientOp::Subscribe { ok, bad } = op else {
            panic!("not a subscribe: {op:?}")
        };
        assert_eq!(
            ok,
            [Subscription {
                id: 0,
                channel_id: 1
            }]
        );
        assert_eq!(bad.len(), 5, "{bad:?}");
        assert_eq!(bad[0], Refusal::BadSubscription { index: 1 });
        assert!(bad[0].to_string().starts_with("subscription 1:"));
        let ClientOp::Unsubscribe { ok, bad } =
            parse_client_message(r#"{"op":"unsubscribe","subscriptionIds":[3, "x", 2.5, 9]}"#)
                .unwrap()
        else {
            panic!("not an unsubscribe")
        };
        assert_eq!((ok, bad.len()), (vec![3, 9], 2));
    }

    #[test]
    fn garbage_and_unknown_ops_are_told_apart() {
        assert!(matches!(
            parse_client_message("{not json"),
            Err(ParseError::NotJson(_))
        ));
        assert_eq!(parse_client_message("[1,2]"), Err(ParseError::NoOp));
        assert_eq!(parse_client_message(r#"{"op":5}"#), Err(ParseError::NoOp));
        assert_eq!(
            parse_client_message(r#"{"op":"subscribe","subscriptions":{}}"#),
            Err(ParseError::NoList("subscriptions"))
        );
        assert_eq!(
            parse_client_message(r#"{"op":"getParameters","parameterNames":[]}"#),
            Ok(ClientOp::Other("getParameters".to_owned()))
        );
    }

    #[test]
    fn subscriptions_refuse_unknown_channels_reused_ids_and_second_subscriptions() {
        let known = |c: u32| (1..=3).contains(&c);
        let mut s = Subscriptions::new();
        let sub = |id, channel_id| Subscription { id, channel_id };
        assert!(s.subscribe(&[sub(0, 1), sub(1, 2)], known).is_empty());
        let refused = s.subscribe(&[sub(2, 9), sub(0, 3), sub(5, 1), sub(6, 3)], known);
        assert_eq!(refused.len(), 3, "{refused:?}");
        assert!(refused[0].to_string().contains("no channel 9"));
        assert!(refused[1].to_string().contains("in use"));
        assert!(refused[2].to_string().contains("already subscribed as 0"));
        assert_eq!(s.len(), 3);
        assert_eq!(s.subscription_of(3), Some(6));
        assert_eq!(s.mask(), 0b1110);
        assert_eq!(s.unsubscribe(&[0, 0, 42]).len(), 2);
        assert_eq!(s.subscription_of(1), None);
        assert_eq!(s.mask(), 0b1100);
        // after unsubscribing, the id may be reused
        assert!(s.subscribe(&[sub(0, 1)], known).is_empty());
        assert_eq!(s.subscription_of(1), Some(0));
    }

    #[test]
    fn a_session_answers_refusals_with_one_error_status_and_takes_the_rest() {
        let channels: Vec<ChannelInfo> = (1..=3)
            .map(|id| ChannelInfo {
                id,
                topic: "/t",
                schema_name: "s",
                schema: String::new(),
            })
            .collect();
        let mut s = SessionState::new(&channels);
        // as FoxgloveClient sends them
        let a = s.handle(Incoming::Text(
            r#"{"op":"subscribe","subscriptions":[{"id":0,"channelId":1}]}"#,
        ));
        assert_eq!(
            a,
            Answer {
                refusals: vec![],
                reply: None
            }
        );
        let a = s.handle(Incoming::Text(
            r#"{"op":"subscribe","subscriptions":[{"id":1,"channelId":2},{"id":0,"channelId":3},{"id":2,"channelId":7}]}"#,
        ));
        let kinds: Vec<&str> = a.refusals.iter().map(Refusal::kind).collect();
        assert_eq!(kinds, ["IdInUse", "UnknownChannel"]);
        let reply: Json = serde_json::from_str(a.reply.as_deref().unwrap()).unwrap();
        assert_eq!(
            reply,
            json!({"op": "status", "level": 2, "message":
                "subscription 0: the id is in use (unsubscribe it first); subscription 2: no channel 7 was advertised"})
        );
        assert_eq!(s.subscriptions().mask(), 0b0110);
        let texts = [
            (
                Incoming::Binary(&[1, 0, 0, 0, 0]),
                "eqtrack-live takes no binary messages (it does not offer clientPublish or services)",
            ),
            (
                Incoming::Text(r#"{"op":"subscribeConnectionGraph"}"#),
                "op `subscribeConnectionGraph` is not supported by eqtrack-live (it only publishes)",
            ),
            (
                Incoming::Text("[1]"),
                "cannot read a client message: not a JSON object with a string `op`",
            ),
        ];
        for (msg, want) in texts {
            let a = s.handle(msg);
            assert_eq!(a.reply, Some(status(Level::Error, want)));
        }
        // more than SHOWN_REFUSALS are counted, not all named
        let a = s.handle(Incoming::Text(
            r#"{"op":"unsubscribe","subscriptionIds":[9,9,9,9,9,9,9,9,9,9,0,1]}"#,
        ));
        assert_eq!(a.refusals.len(), 10);
        let reply: Json = serde_json::from_str(a.reply.as_deref().unwrap()).unwrap();
        assert_eq!(
            reply["message"].as_str().unwrap().matches("; ").count(),
            SHOWN_REFUSALS - 1
        );
        assert!(s.subscriptions().is_empty());
        assert_eq!(s.subscriptions().mask(), 0);
    }

    proptest! {
        #[test]
        fn no_text_makes_the_parser_panic(text in ".{0,256}") {
            let _ = parse_client_message(&text);
        }

        #[test]
        fn no_json_shaped_text_makes_the_parser_or_the_subscriptions_panic(
            op in prop_oneof![
                Just("subscribe".to_owned()),
                Just("unsubscribe".to_owned()),
                ".{0,12}",
            ],
            ids in prop::collection::vec(
                prop_oneof![
                    any::<i64>().prop_map(|x| x.to_string()),
                    any::<f64>().prop_map(|x| format!("{x:?}")),
                    ".{0,8}".prop_map(|s| format!("{s:?}")),
                    Just("null".to_owned()),
                    Just("{}".to_owned()),
                ],
                0..6,
            ),
        ) {
            let subs: Vec<String> = ids
                .chunks(2)
                .map(|p| format!(r#"{{"id":{},"channelId":{}}}"#, p[0], p.get(1).map_or("1", |s| s)))
                .collect();
            let text = format!(
                r#"{{"op":{op:?},"subscriptions":[{}],"subscriptionIds":[{}]}}"#,
                subs.join(","),
                ids.join(",")
            );
            let mut s = Subscriptions::new();
            match parse_client_message(&text) {
                Ok(ClientOp::Subscribe { ok, .. }) => {
                    let _ = s.subscribe(&ok, |c| c < 4);
                    prop_assert!(s.len() <= ok.len());
                }
                Ok(ClientOp::Unsubscribe { ok, .. }) => {
                    prop_assert_eq!(s.unsubscribe(&ok).len(), ok.len());
                }
                Ok(ClientOp::Other(_)) | Err(_) => {}
            }
        }
    }
}
