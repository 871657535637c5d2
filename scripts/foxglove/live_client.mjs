// A Foxglove WebSocket client no one in this project wrote: @foxglove/ws-protocol's
// FoxgloveClient over the `ws` package (Node 20 has no global WebSocket), decoding with
// @foxglove/rosmsg and @foxglove/rosmsg2-serialization, the libraries Foxglove's app uses.
//
//     node live_client.mjs URL SUBPROTOCOL OUT.json
//
// Connects to the bridge (`plant_sim live`) offering SUBPROTOCOL, checks serverInfo and the
// advertised channels, subscribes to /eqtrack/state, /eqtrack/command and /eqtrack/status,
// decodes every message with its channel's ros2msg schema, and when the bridge closes (the
// run ended) writes what it got to OUT.json: the serverInfo, the status messages, and per
// message its topic, log time and decoded fields. Prints `subscribed` once it has
// subscribed. Exits 1 on an error or if the bridge does not close within 120 s.
import { writeFileSync } from "node:fs";
import wsProtocol from "@foxglove/ws-protocol"; // CommonJS: no named exports under Node
import { parse } from "@foxglove/rosmsg";
import { MessageReader } from "@foxglove/rosmsg2-serialization";
import WebSocket from "ws";

const { FoxgloveClient } = wsProtocol;

const [url, subprotocol, outPath] = process.argv.slice(2);
const fail = (msg) => {
  console.error(`live client (${subprotocol}): ${msg}`);
  process.exit(1);
};
const TOPICS = ["/eqtrack/state", "/eqtrack/command", "/eqtrack/status"];

// decoded values as JSON: bigints as strings, typed arrays as arrays, NaN and infinities as
// the export's strings
const plain = (v) => {
  if (typeof v === "bigint") return v.toString();
  if (ArrayBuffer.isView(v) || Array.isArray(v)) return Array.from(v, plain);
  if (typeof v === "number" && !Number.isFinite(v)) return Number.isNaN(v) ? "NaN" : v > 0 ? "inf" : "-inf";
  return v;
};

const ws = new WebSocket(url, [subprotocol]);
ws.on("upgrade", (res) => {
  const got = res.headers["sec-websocket-protocol"];
  if (got !== subprotocol) fail(`the server answered subprotocol ${got}, offered ${subprotocol}`);
});
const client = new FoxgloveClient({ ws });
const out = { subprotocol, serverInfo: null, channels: [], statuses: [], messages: [] };
const bySubscription = new Map();
client.on("error", (e) => fail(`error: ${e?.message ?? e}`));
client.on("serverInfo", (info) => {
  out.serverInfo = info;
});
client.on("status", (s) => {
  out.statuses.push({ level: s.level, message: s.message });
  if (s.level === 2 && !/gone|did not start/.test(s.message)) fail(`error status: ${s.message}`);
});
client.on("advertise", (channels) => {
  if (out.serverInfo === null) fail("advertise before serverInfo");
  for (const ch of channels) {
    out.channels.push({ id: ch.id, topic: ch.topic, encoding: ch.encoding, schemaName: ch.schemaName, schemaEncoding: ch.schemaEncoding });
    if (!TOPICS.includes(ch.topic)) continue;
    if (ch.encoding !== "cdr" || ch.schemaEncoding !== "ros2msg") fail(`${ch.topic}: ${ch.encoding}/${ch.schemaEncoding}`);
    const reader = new MessageReader(parse(ch.schema, { ros2: true }));
    bySubscription.set(client.subscribe(ch.id), { topic: ch.topic, reader });
  }
  if (bySubscription.size === TOPICS.length) console.log("subscribed");
});
client.on("message", ({ subscriptionId, timestamp, data }) => {
  const sub = bySubscription.get(subscriptionId);
  if (sub === undefined) fail(`a message for subscription ${subscriptionId}, never made`);
  const decoded = sub.reader.readMessage(new Uint8Array(data.buffer, data.byteOffset, data.byteLength));
  const fields = Object.fromEntries(Object.entries(decoded).map(([k, v]) => [k, plain(v)]));
  out.messages.push({ topic: sub.topic, log_time: timestamp.toString(), fields });
});
client.on("close", () => {
  writeFileSync(outPath, JSON.stringify(out));
  console.log(`closed: ${out.messages.length} messages, ${out.statuses.length} status messages`);
  process.exit(0);
});
setTimeout(() => fail("the bridge did not close within 120 s"), 120_000).unref();
