//! The live target: what a Foxglove client sends the live bridge (`eqtrack-live`,
//! docs/live.md), a sequence of WebSocket messages through one client session's handling of
//! them ([`live::protocol::SessionState::handle`]: the client-message parser
//! `parse_client_message`, then the session's subscriptions). A text message is JSON (or
//! not), a binary message anything.
//!
//! The oracle, after every message: no panic; every refusal is a [`Refusal`] (a typed,
//! named error), and the answer is an error `status` message exactly when something was
//! refused, valid JSON naming the first [`SHOWN_REFUSALS`] refusals and never longer than
//! [`MAX_REPLY`]; the subscriptions are consistent (ids unique, at most one per channel, only
//! advertised channels, the channel mask and `subscription_of` agreeing with the list) and
//! equal to those of a reference model of the protocol's rules fed the same parsed message
//! (a `subscribe` takes the entries whose channel was advertised and whose id and channel are
//! free, an `unsubscribe` removes the ids it names, anything else changes nothing), with the
//! refusals the model expects, in order. At the end of the sequence, an `unsubscribe` of
//! every active id is taken without refusal and leaves none, and all the channels can then
//! be subscribed again.
//!
//! Seeds: the sequences FoxgloveClient (npm's `@foxglove/ws-protocol`) and Foxglove's app
//! send (one `subscribe` per channel with ids counting from 0, or one for all; `unsubscribe`
//! of one id or of all), and, to insert, the other things clients send: the ops of the
//! capabilities the bridge does not declare (`advertise`, `getParameters`,
//! `subscribeConnectionGraph`, `fetchAsset`, ...) and the client's binary messages
//! (`clientPublish` data, a service call request). Mutations: the byte-level ones on one
//! message; a JSON number replaced (ids past `u32`, negative, fractional, exponents, 20
//! digits), a string replaced (the op, a key, long or escaped text); a JSON value replaced
//! with another type, removed, duplicated, wrapped in an array or object, or a list of up to
//! 300 entries put in its place; deep nesting (to 5000 levels, past `serde_json`'s limit of
//! 128); messages duplicated, removed, swapped, inserted from the seeds, turned text to
//! binary or back; random bytes.
//!
//! A case's bytes are the messages in order, each as a tag byte (bit 0: binary), its length
//! (u32, little-endian) and its bytes ([`crate::live_messages`] reads them back); a text
//! message's invalid UTF-8 is replaced (the WebSocket library refuses such text before the
//! bridge sees it).

use crate::LiveMessage;
use crate::mutate::{ByteOp, MAX_INPUT, byte_op};
use crate::rng::Gen;
use crate::scenario_target::{number_spans, string_spans};
use crate::{Outcome, live_messages};
use live::protocol::{
    ChannelInfo, ClientOp, Incoming, Level, Refusal, SHOWN_REFUSALS, SessionState, Subscription,
    parse_client_message,
};
use serde_json::{Value as Json, json};
use std::collections::BTreeMap;
use std::sync::OnceLock;

/// The longest answer the bridge may send to one message, in bytes: [`SHOWN_REFUSALS`]
/// refusals of at most a few hundred bytes each (an unknown op is cut to 64 characters).
pub(crate) const MAX_REPLY: usize = 4096;

/// Messages in a case, at most.
const MAX_MESSAGES: usize = 32;

/// The bridge's advertised channels (built once: their schema texts take a while).
fn channels() -> &'static [ChannelInfo] {
    static CHANNELS: OnceLock<Vec<ChannelInfo>> = OnceLock::new();
    CHANNELS.get_or_init(live::channel_infos)
}

/// `subscribe` as FoxgloveClient sends it (`JSON.stringify`): `(id, channelId)` pairs.
fn subscribe(subs: &[(u32, u32)]) -> LiveMessage {
    let list: Vec<String> = subs
        .iter()
        .map(|(id, ch)| format!(r#"{{"id":{id},"channelId":{ch}}}"#))
        .collect();
    LiveMessage::Text(format!(
        r#"{{"op":"subscribe","subscriptions":[{}]}}"#,
        list.join(",")
    ))
}

/// `unsubscribe` as FoxgloveClient sends it.
fn unsubscribe(ids: &[u32]) -> LiveMessage {
    let ids: Vec<String> = ids.iter().map(u32::to_string).collect();
    LiveMessage::Text(format!(
        r#"{{"op":"unsubscribe","subscriptionIds":[{}]}}"#,
        ids.join(",")
    ))
}

fn text(t: &str) -> LiveMessage {
    LiveMessage::Text(t.to_owned())
}

/// The seed sequences: what real clients send, accepted all the way.
fn seed_sequences() -> Vec<Vec<LiveMessage>> {
    vec![
        // FoxgloveClient.subscribe per channel (scripts/foxglove/live_client.mjs)
        vec![
            subscribe(&[(0, 1)]),
            subscribe(&[(1, 2)]),
            subscribe(&[(2, 3)]),
        ],
        vec![subscribe(&[(0, 1)])],
        // Foxglove's app: the topics of a layout at once, then one panel's topic dropped
        vec![subscribe(&[(0, 1), (1, 2), (2, 3)]), unsubscribe(&[1])],
        // every one dropped, one at a time, and subscribed again with the next ids
        vec![
            subscribe(&[(0, 1)]),
            subscribe(&[(1, 2)]),
            subscribe(&[(2, 3)]),
            unsubscribe(&[0]),
            unsubscribe(&[1]),
            unsubscribe(&[2]),
            subscribe(&[(3, 1)]),
            subscribe(&[(4, 3)]),
        ],
        // all at once, none, and an id reused once free
        vec![
            subscribe(&[(0, 3), (1, 1)]),
            unsubscribe(&[0, 1]),
            subscribe(&[(0, 1)]),
        ],
        // the largest ids
        vec![
            subscribe(&[(u32::MAX, 2), (u32::MAX - 1, 1)]),
            unsubscribe(&[u32::MAX]),
        ],
    ]
}

/// Other messages clients send: what a client of more capabilities asks (all refused by the
/// bridge, which declares none), garbage, and the client's binary messages.
fn other_messages() -> Vec<LiveMessage> {
    let mut publish = vec![0x01];
    publish.extend_from_slice(&1u32.to_le_bytes());
    publish.extend_from_slice(&[0, 1, 0, 0, 42, 0, 0, 0]);
    let mut call = vec![0x02];
    for x in [1u32, 7, 3] {
        call.extend_from_slice(&x.to_le_bytes());
    }
    call.extend_from_slice(b"cdr\x00\x01\x00\x00");
    vec![
        text(r#"{"op":"subscribeConnectionGraph"}"#),
        text(r#"{"op":"unsubscribeConnectionGraph"}"#),
        text(r#"{"op":"getParameters","parameterNames":["/kp"],"id":"request-1"}"#),
        text(r#"{"op":"setParameters","parameters":[{"name":"/kp","value":1}],"id":"2"}"#),
        text(r#"{"op":"subscribeParameterUpdates","parameterNames":["/kd"]}"#),
        text(
            r#"{"op":"advertise","channels":[{"id":1,"topic":"/cmd","encoding":"json","schemaName":"Cmd"}]}"#,
        ),
        text(r#"{"op":"unadvertise","channelIds":[1]}"#),
        text(r#"{"op":"fetchAsset","uri":"package://eqtrack/mesh.stl","requestId":1}"#),
        text(r#"{"op":"subscribe"}"#),
        text(r#"{"op":"unsubscribe","subscriptionIds":{}}"#),
        text(r#"{"op":"subscribe","subscriptions":[{"id":0,"channelId":99}]}"#),
        text("{not json"),
        text(""),
        text("[]"),
        text("null"),
        LiveMessage::Binary(publish),
        LiveMessage::Binary(call),
        LiveMessage::Binary(Vec::new()),
    ]
}

/// The mutations, with their weights.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum LiveOp {
    /// A byte-level mutation of one message.
    Byte(ByteOp),
    /// A number in a text message replaced.
    Number,
    /// A string's text in a text message replaced.
    String,
    /// One JSON value of a text message replaced, removed, duplicated or wrapped.
    Value,
    /// A list of many entries put in a text message.
    LongList,
    /// A text message nested deep in arrays or objects.
    Nest,
    /// A message duplicated.
    Duplicate,
    /// A message removed.
    Remove,
    /// Two messages swapped.
    Swap,
    /// A message of the seeds or the other messages inserted.
    Insert,
    /// A text message sent as binary, or a binary one as text.
    Flip,
    /// A message of random bytes inserted.
    Random,
}

const OPS: [(LiveOp, u32); 18] = [
    (LiveOp::Byte(ByteOp::BitFlip), 2),
    (LiveOp::Byte(ByteOp::Overwrite), 3),
    (LiveOp::Byte(ByteOp::Insert), 2),
    (LiveOp::Byte(ByteOp::Delete), 2),
    (LiveOp::Byte(ByteOp::Truncate), 1),
    (LiveOp::Byte(ByteOp::DuplicateChunk), 2),
    (LiveOp::Byte(ByteOp::Splice), 1),
    (LiveOp::Number, 14),
    (LiveOp::String, 6),
    (LiveOp::Value, 12),
    (LiveOp::LongList, 2),
    (LiveOp::Nest, 1),
    (LiveOp::Duplicate, 6),
    (LiveOp::Remove, 4),
    (LiveOp::Swap, 4),
    (LiveOp::Insert, 6),
    (LiveOp::Flip, 1),
    (LiveOp::Random, 1),
];

/// The numbers a JSON number is replaced with (besides random ones).
const NUMBERS: [&str; 22] = [
    "0",
    "1",
    "2",
    "3",
    "4",
    "31",
    "32",
    "-1",
    "-0",
    "1.0",
    "1.5",
    "1e0",
    "3e0",
    "1e400",
    "4294967295",
    "4294967296",
    "9007199254740993",
    "18446744073709551615",
    "18446744073709551616",
    "99999999999999999999999",
    "0.1e1",
    "-4294967296",
];

/// The texts a JSON string is replaced with.
const STRINGS: [&str; 16] = [
    "subscribe",
    "unsubscribe",
    "Subscribe",
    "",
    "op",
    "id",
    "channelId",
    "subscriptions",
    "subscriptionIds",
    "advertise",
    "subscribe\\u0000",
    "\\ud800",
    "\\\"",
    "é\\n\\t",
    "1",
    "getParameters",
];

/// The seed corpus and the mutator of the live target.
pub(crate) struct Corpus {
    sequences: Vec<Vec<LiveMessage>>,
    singles: Vec<LiveMessage>,
}

impl Corpus {
    /// The seed sequences and the messages to insert.
    pub(crate) fn new() -> Corpus {
        let sequences = seed_sequences();
        let mut singles = other_messages();
        singles.extend(sequences.iter().flatten().cloned());
        Corpus { sequences, singles }
    }

    /// One case: a seed sequence with 1–8 mutations, encoded.
    pub(crate) fn generate(&self, g: &mut Gen) -> Vec<u8> {
        let mut msgs = g.pick(&self.sequences).clone();
        for _ in 0..g.mutation_count() {
            let op = g.pick_weighted(&OPS);
            self.mutate(g, op, &mut msgs);
        }
        msgs.truncate(MAX_MESSAGES);
        encode(&msgs)
    }

    fn mutate(&self, g: &mut Gen, op: LiveOp, msgs: &mut Vec<LiveMessage>) {
        if msgs.is_empty() {
            msgs.push(g.pick(&self.singles).clone());
            return;
        }
        let i = g.below(msgs.len());
        match op {
            LiveOp::Byte(b) => {
                let other = message_bytes(g.pick(&self.singles)).to_vec();
                let mut data = message_bytes(&msgs[i]).to_vec();
                byte_op(g, b, &mut data, &other);
                msgs[i] = msgs[i].with_bytes(data);
            }
            LiveOp::Number => edit_text(&mut msgs[i], |t| replace_number(g, t)),
            LiveOp::String => edit_text(&mut msgs[i], |t| replace_string(g, t)),
            LiveOp::Value => edit_text(&mut msgs[i], |t| edit_value(g, t)),
            LiveOp::LongList => edit_text(&mut msgs[i], |t| long_list(g, t)),
            LiveOp::Nest => edit_text(&mut msgs[i], |t| nest(g, t)),
            LiveOp::Duplicate => {
                let m = msgs[i].clone();
                let at = g.below(msgs.len() + 1);
                msgs.insert(at, m);
            }
            LiveOp::Remove => {
                msgs.remove(i);
            }
            LiveOp::Swap => {
                let j = g.below(msgs.len());
                msgs.swap(i, j);
            }
            LiveOp::Insert => {
                let m = g.pick(&self.singles).clone();
                let at = g.below(msgs.len() + 1);
                msgs.insert(at, m);
            }
            LiveOp::Flip => {
                msgs[i] = match &msgs[i] {
                    LiveMessage::Text(t) => LiveMessage::Binary(t.clone().into_bytes()),
                    LiveMessage::Binary(b) => LiveMessage::Text(String::from_utf8_lossy(b).into()),
                };
            }
            LiveOp::Random => {
                let n = g.range(0, 64);
                let bytes = if g.chance(1, 2) {
                    g.bytes(n)
                } else {
                    // printable, JSON-ish
                    let alphabet = b"{}[]:,\"0123456789-.eE opidchanelsubcrt\\";
                    (0..n).map(|_| *g.pick(alphabet)).collect()
                };
                let m = if g.chance(1, 3) {
                    LiveMessage::Binary(bytes)
                } else {
                    LiveMessage::Text(String::from_utf8_lossy(&bytes).into())
                };
                let at = g.below(msgs.len() + 1);
                msgs.insert(at, m);
            }
        }
    }
}

impl LiveMessage {
    /// The same kind of message with other bytes (text: invalid UTF-8 replaced).
    fn with_bytes(&self, bytes: Vec<u8>) -> LiveMessage {
        match self {
            LiveMessage::Text(_) => LiveMessage::Text(match String::from_utf8(bytes) {
                Ok(s) => s,
                Err(e) => String::from_utf8_lossy(e.as_bytes()).into_owned(),
            }),
            LiveMessage::Binary(_) => LiveMessage::Binary(bytes),
        }
    }
}

fn message_bytes(m: &LiveMessage) -> &[u8] {
    match m {
        LiveMessage::Text(t) => t.as_bytes(),
        LiveMessage::Binary(b) => b,
    }
}

/// Applies `edit` to a text message (a binary one is left as it is).
fn edit_text(m: &mut LiveMessage, edit: impl FnOnce(&mut String)) {
    if let LiveMessage::Text(t) = m {
        edit(t);
        if t.len() > MAX_INPUT {
            let mut cut = MAX_INPUT;
            while !t.is_char_boundary(cut) {
                cut -= 1;
            }
            t.truncate(cut);
        }
    }
}

/// The messages as a case's bytes: per message a tag (0 text, 1 binary), its length (u32
/// LE) and its bytes; messages past [`MAX_INPUT`] bytes in all are dropped.
pub(crate) fn encode(msgs: &[LiveMessage]) -> Vec<u8> {
    let mut out = Vec::new();
    for m in msgs {
        let (tag, bytes) = match m {
            LiveMessage::Text(t) => (0u8, t.as_bytes()),
            LiveMessage::Binary(b) => (1u8, b.as_slice()),
        };
        if out.len() + 5 + bytes.len() > MAX_INPUT {
            break;
        }
        out.push(tag);
        out.extend_from_slice(&(bytes.len() as u32).to_le_bytes());
        out.extend_from_slice(bytes);
    }
    out
}

/// A random number text: [`NUMBERS`], or a random integer or float.
fn number(g: &mut Gen) -> String {
    match g.below(5) {
        0 => (g.u32()).to_string(),
        1 => (g.u64()).to_string(),
        2 => format!("{}", g.u64() as i64),
        3 => format!("{:e}", (g.u64() % 1_000_000) as f64 / 7.0),
        _ => (*g.pick(&NUMBERS)).to_owned(),
    }
}

fn replace_number(g: &mut Gen, t: &mut String) {
    let spans = number_spans(t.as_bytes());
    let n = number(g);
    if spans.is_empty() {
        return;
    }
    let (a, b) = *g.pick(&spans);
    // the spans are of ASCII bytes: the cut is at a character boundary
    if t.is_char_boundary(a) && t.is_char_boundary(b) {
        t.replace_range(a..b, &n);
    }
}

fn replace_string(g: &mut Gen, t: &mut String) {
    let spans = string_spans(t.as_bytes());
    if spans.is_empty() {
        return;
    }
    let (a, b) = *g.pick(&spans);
    let s = match g.below(4) {
        0 => "x".repeat(g.range(60, 300)),
        1 => "é".repeat(g.range(30, 100)),
        _ => (*g.pick(&STRINGS)).to_owned(),
    };
    if t.is_char_boundary(a) && t.is_char_boundary(b) {
        t.replace_range(a..b, &s);
    }
}

/// A JSON value of another type, or a change of `old`.
fn other_value(g: &mut Gen, old: &Json) -> Json {
    match g.below(12) {
        0 => Json::Null,
        1 => json!(true),
        2 => json!([]),
        3 => json!({}),
        4 => json!([old.clone()]),
        5 => json!({ "id": old.clone() }),
        6 => json!(g.pick(&STRINGS).replace('\\', "")),
        7 => json!({"id": g.below(5), "channelId": g.below(5)}),
        8 => json!(g.below(5)),
        9 => json!(-(g.below(3) as i64) - 1),
        10 => json!(1.5),
        _ => serde_json::from_str(&number(g)).unwrap_or(Json::Null),
    }
}

/// Every value of `v`, as JSON pointers.
fn pointers(v: &Json, at: String, out: &mut Vec<String>) {
    match v {
        Json::Array(a) => {
            for (i, x) in a.iter().enumerate() {
                pointers(x, format!("{at}/{i}"), out);
            }
        }
        Json::Object(o) => {
            for (k, x) in o {
                pointers(
                    x,
                    format!("{at}/{}", k.replace('~', "~0").replace('/', "~1")),
                    out,
                );
            }
        }
        _ => {}
    }
    out.push(at);
}

/// One value of the message replaced, removed, duplicated, or a key added.
fn edit_value(g: &mut Gen, t: &mut String) {
    let Ok(mut v) = serde_json::from_str::<Json>(t) else {
        return;
    };
    let mut ptrs = Vec::new();
    pointers(&v, String::new(), &mut ptrs);
    let ptr = g.pick(&ptrs).clone();
    let (parent, last) = ptr.rsplit_once('/').unwrap_or(("", ""));
    match g.below(4) {
        // replaced
        0 | 1 => {
            if let Some(x) = v.pointer_mut(&ptr) {
                *x = other_value(g, x);
            }
        }
        // removed
        2 => match v.pointer_mut(parent) {
            Some(Json::Array(a)) => {
                if let Ok(i) = last.parse::<usize>()
                    && i < a.len()
                {
                    a.remove(i);
                }
            }
            Some(Json::Object(o)) => {
                o.remove(&last.replace("~1", "/").replace("~0", "~"));
            }
            _ => {}
        },
        // duplicated in its array, or a key added beside it
        _ => match v.pointer_mut(parent) {
            Some(Json::Array(a)) => {
                if let Ok(i) = last.parse::<usize>()
                    && i < a.len()
                {
                    let x = a[i].clone();
                    a.insert(g.below(a.len() + 1), x);
                }
            }
            Some(Json::Object(o)) => {
                let key = g.pick(&STRINGS).replace('\\', "");
                let x = other_value(g, &Json::Null);
                o.insert(key, x);
            }
            _ => {}
        },
    }
    *t = v.to_string();
}

/// A list of up to 300 entries in place of a value: subscriptions or ids.
fn long_list(g: &mut Gen, t: &mut String) {
    let Ok(mut v) = serde_json::from_str::<Json>(t) else {
        return;
    };
    let n = g.range(9, 300);
    let small = g.chance(1, 2);
    let mut id = || {
        if small {
            json!(g.below(8))
        } else {
            json!(g.u32())
        }
    };
    let list: Vec<Json> = (0..n).map(|_| id()).collect();
    let subs: Vec<Json> = list
        .iter()
        .enumerate()
        .map(|(i, x)| json!({"id": x, "channelId": i % 5}))
        .collect();
    if let Json::Object(o) = &mut v {
        if o.contains_key("subscriptionIds") || g.chance(1, 3) {
            o.insert("subscriptionIds".into(), Json::Array(list));
        } else {
            o.insert("subscriptions".into(), Json::Array(subs));
        }
    }
    *t = v.to_string();
}

/// The message nested `depth` levels deep (past serde_json's limit of 128, or not).
fn nest(g: &mut Gen, t: &mut String) {
    let depth = *g.pick(&[2usize, 64, 127, 128, 129, 1000, 5000]);
    let (open, close) = if g.chance(1, 2) {
        ("[", "]")
    } else {
        (r#"{"op":"#, "}")
    };
    let inner = std::mem::take(t);
    *t = format!("{}{inner}{}", open.repeat(depth), close.repeat(depth));
}

/// What the reference model expects of one message: the refusals, in order.
fn model(
    subs: &mut BTreeMap<u32, u32>,
    advertised: impl Fn(u32) -> bool,
    msg: &LiveMessage,
) -> Vec<Refusal> {
    let text = match msg {
        LiveMessage::Binary(_) => return vec![Refusal::Binary],
        LiveMessage::Text(t) => t,
    };
    match parse_client_message(text) {
        Err(e) => vec![Refusal::Unreadable(e)],
        Ok(ClientOp::Other(op)) => {
            assert!(op.chars().count() <= 64, "an op longer than 64 characters");
            vec![Refusal::Unsupported { op }]
        }
        Ok(ClientOp::Subscribe { ok, mut bad }) => {
            assert!(
                bad.iter()
                    .all(|r| matches!(r, Refusal::BadSubscription { .. })),
                "a subscribe's malformed entries: {bad:?}"
            );
            for Subscription { id, channel_id } in ok {
                if !advertised(channel_id) {
                    bad.push(Refusal::UnknownChannel { id, channel_id });
                } else if subs.contains_key(&id) {
                    bad.push(Refusal::IdInUse { id });
                } else if let Some((&existing, _)) = subs.iter().find(|(_, c)| **c == channel_id) {
                    bad.push(Refusal::ChannelTaken {
                        id,
                        channel_id,
                        existing,
                    });
                } else {
                    subs.insert(id, channel_id);
                }
            }
            bad
        }
        Ok(ClientOp::Unsubscribe { ok, mut bad }) => {
            assert!(
                bad.iter()
                    .all(|r| matches!(r, Refusal::BadSubscriptionId { .. })),
                "an unsubscribe's malformed ids: {bad:?}"
            );
            for id in ok {
                if subs.remove(&id).is_none() {
                    bad.push(Refusal::NotSubscribed { id });
                }
            }
            bad
        }
    }
}

/// The session's subscriptions are consistent, and those of the model.
fn assert_consistent(state: &SessionState, model: &BTreeMap<u32, u32>) {
    let subs = state.subscriptions();
    let list: Vec<Subscription> = subs.iter().collect();
    assert!(
        list.windows(2).all(|w| w[0].id < w[1].id),
        "duplicate subscription ids: {list:?}"
    );
    let mut mask = 0u32;
    for s in &list {
        assert!(
            state.advertised(s.channel_id),
            "a subscription to channel {}, never advertised",
            s.channel_id
        );
        assert!(
            mask & (1 << s.channel_id) == 0,
            "channel {} subscribed twice: {list:?}",
            s.channel_id
        );
        mask |= 1 << s.channel_id;
        assert_eq!(subs.subscription_of(s.channel_id), Some(s.id));
    }
    assert_eq!(subs.mask(), mask, "the mask differs from the list {list:?}");
    assert_eq!(subs.len(), list.len());
    assert_eq!(subs.is_empty(), list.is_empty());
    for c in channels() {
        if mask & (1 << c.id) == 0 {
            assert_eq!(subs.subscription_of(c.id), None);
        }
    }
    let modelled: Vec<Subscription> = model
        .iter()
        .map(|(&id, &channel_id)| Subscription { id, channel_id })
        .collect();
    assert_eq!(
        list, modelled,
        "the session differs from the protocol's rules"
    );
}

/// The answer to refusals: an error `status`, valid JSON, naming the first of them.
fn assert_reply(reply: &str, refusals: &[Refusal]) {
    assert!(
        reply.len() <= MAX_REPLY,
        "an answer of {} bytes",
        reply.len()
    );
    let v: Json = serde_json::from_str(reply).expect("the answer is JSON");
    assert_eq!(v["op"], "status", "{reply}");
    assert_eq!(v["level"], 2, "{reply}");
    let shown: Vec<String> = refusals
        .iter()
        .take(SHOWN_REFUSALS)
        .map(ToString::to_string)
        .collect();
    assert_eq!(v["message"], json!(shown.join("; ")), "{reply}");
    assert_eq!(
        reply,
        live::protocol::status(Level::Error, &shown.join("; "))
    );
}

/// The oracle (see the module's documentation).
pub(crate) fn check(bytes: &[u8]) -> Outcome {
    let msgs = live_messages(bytes);
    let mut state = SessionState::new(channels());
    let mut expected = BTreeMap::new();
    let mut first: Option<&'static str> = None;
    for msg in &msgs {
        let want = model(&mut expected, |c| state.advertised(c), msg);
        let incoming = match msg {
            LiveMessage::Text(t) => Incoming::Text(t),
            LiveMessage::Binary(b) => Incoming::Binary(b),
        };
        let answer = state.handle(incoming);
        assert_eq!(answer.refusals, want, "the refusals of {msg:?}");
        for r in &answer.refusals {
            assert!(!r.kind().is_empty() && !r.to_string().is_empty());
        }
        match &answer.reply {
            Some(reply) => assert_reply(reply, &answer.refusals),
            None => assert!(answer.refusals.is_empty(), "refused without an answer"),
        }
        assert_consistent(&state, &expected);
        if let Some(r) = answer.refusals.first() {
            first.get_or_insert(r.kind());
        }
    }
    // an unsubscribe of all leaves none; then every channel can be subscribed again
    let ids: Vec<u32> = state.subscriptions().iter().map(|s| s.id).collect();
    let all = json!({"op": "unsubscribe", "subscriptionIds": ids}).to_string();
    let answer = state.handle(Incoming::Text(&all));
    assert!(
        answer.refusals.is_empty() && answer.reply.is_none(),
        "unsubscribing every active id: {answer:?}"
    );
    assert!(state.subscriptions().is_empty() && state.subscriptions().mask() == 0);
    let again: Vec<(u32, u32)> = channels().iter().map(|c| (c.id + 100, c.id)).collect();
    let LiveMessage::Text(again) = subscribe(&again) else {
        unreachable!()
    };
    let answer = state.handle(Incoming::Text(&again));
    assert!(answer.refusals.is_empty(), "{answer:?}");
    assert_eq!(state.subscriptions().len(), channels().len());
    match first {
        None => Outcome::Accepted,
        Some(kind) => Outcome::Rejected(format!("live: {kind}")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Streams;

    #[test]
    fn the_seeds_are_accepted_and_the_other_messages_refused() {
        for seq in seed_sequences() {
            assert_eq!(check(&encode(&seq)), Outcome::Accepted, "{seq:?}");
        }
        for m in other_messages() {
            assert!(
                matches!(
                    check(&encode(std::slice::from_ref(&m))),
                    Outcome::Rejected(_)
                ),
                "{m:?}"
            );
        }
    }

    #[test]
    fn cases_round_trip_through_their_bytes() {
        let c = Corpus::new();
        let s = Streams::new(3);
        for i in 0..500 {
            let bytes = c.generate(&mut s.case(i));
            assert!(bytes.len() <= MAX_INPUT);
            let msgs = live_messages(&bytes);
            assert_eq!(encode(&msgs), bytes, "case {i}");
        }
    }

    #[test]
    fn deep_nesting_is_refused_as_not_json() {
        let mut g = Streams::new(1).case(0);
        for _ in 0..20 {
            let mut t = r#"{"op":"subscribe","subscriptions":[]}"#.to_owned();
            nest(&mut g, &mut t);
            let _ = check(&encode(&[LiveMessage::Text(t)]));
        }
        // (within a case's 16 KiB)
        for (open, close, depth) in [("[", "]", 5000), (r#"{"op":"#, "}", 2000)] {
            let deep = format!("{}1{}", open.repeat(depth), close.repeat(depth));
            assert_eq!(live_messages(&encode(&[text(&deep)])).len(), 1);
            assert_eq!(
                check(&encode(&[LiveMessage::Text(deep)])),
                Outcome::Rejected("live: NotJson".to_owned())
            );
        }
    }

    #[test]
    fn a_session_that_broke_the_rules_would_be_caught() {
        // the model refuses a second subscription of a channel; a session that took it
        // would differ from the model, which the oracle asserts
        let mut model_subs = BTreeMap::new();
        let known = |c: u32| (1..=3).contains(&c);
        let m = subscribe(&[(0, 1), (1, 1)]);
        let want = model(&mut model_subs, known, &m);
        assert_eq!(
            want,
            [Refusal::ChannelTaken {
                id: 1,
                channel_id: 1,
                existing: 0
            }]
        );
        let mut state = SessionState::new(channels());
        let LiveMessage::Text(t) = subscribe(&[(0, 1), (1, 2)]) else {
            unreachable!()
        };
        state.handle(Incoming::Text(&t));
        let caught = std::panic::catch_unwind(|| assert_consistent(&state, &model_subs));
        assert!(caught.is_err(), "a session other than the model passed");
    }
}
