// Reads an eqtrack MCAP export with the TypeScript libraries Foxglove's own app decodes with
// (@mcap/core, @foxglove/rosmsg, @foxglove/rosmsg2-serialization), under Node, and checks it
// against the project's own reading of the same messages.log (`eqtrack-export --format jsonl`):
//
//     node check_mcap.mjs RUN.mcap RUN.jsonl
//
// CRCs are validated; every message is decoded with its channel's ros2msg schema; the counts
// per topic equal the JSONL's, log_time never decreases and equals publish_time, each
// sequence is the JSONL's cycle index, and a sample of messages (every
// 97th, and the first and last) equals the JSONL field by field (NaN as NaN). Exits 1 on the
// first disagreement.
import { readFileSync } from "node:fs";
import { McapStreamReader } from "@mcap/core";
import { parse } from "@foxglove/rosmsg";
import { MessageReader } from "@foxglove/rosmsg2-serialization";

const [mcapPath, jsonlPath] = process.argv.slice(2);
const expected = readFileSync(jsonlPath, "utf8").trim().split("\n").map((l) => JSON.parse(l));
const fail = (msg) => {
  console.error(`node mcap: ${msg}`);
  process.exit(1);
};

const same = (got, want) => {
  if (Array.isArray(want)) {
    const g = Array.from(got);
    return g.length === want.length && want.every((w, i) => same(g[i], w));
  }
  if (want === "NaN") return Number.isNaN(got);
  if (want === "inf") return got === Infinity;
  if (want === "-inf") return got === -Infinity;
  if (typeof got === "bigint") return got === BigInt(want);
  if (typeof want === "boolean") return Boolean(got) === want;
  return got === want;
};

const reader = new McapStreamReader({ validateCrcs: true });
reader.append(readFileSync(mcapPath));
const schemas = new Map();
const channels = new Map();
const counts = {};
let index = 0;
let lastTime = -1n;
let checked = 0;
let metadata = null;
for (let record; (record = reader.nextRecord()); ) {
  if (record.type === "Schema") {
    schemas.set(record.id, record);
  } else if (record.type === "Channel") {
    const schema = schemas.get(record.schemaId);
    if (schema.encoding !== "ros2msg" || record.messageEncoding !== "cdr") {
      fail(`channel ${record.topic}: ${schema.encoding}/${record.messageEncoding}`);
    }
    const text = new TextDecoder().decode(schema.data);
    channels.set(record.id, { topic: record.topic, schema: schema.name, reader: new MessageReader(parse(text, { ros2: true })) });
  } else if (record.type === "Message") {
    const ch = channels.get(record.channelId);
    const decoded = ch.reader.readMessage(record.data);
    const want = expected[index];
    if (want === undefined) fail(`more messages than the JSONL's ${expected.length}`);
    const where = `message ${index} (${ch.topic}, cycle ${want.sequence})`;
    if (ch.topic !== want.topic || ch.schema !== want.schema) fail(`${where}: topic ${ch.topic}, expected ${want.topic}`);
    if (record.logTime < lastTime) fail(`${where}: log_time decreases`);
    lastTime = record.logTime;
    if (record.logTime !== BigInt(want.log_time)) fail(`${where}: log_time ${record.logTime}, expected ${want.log_time}`);
    if (record.publishTime !== record.logTime) fail(`${where}: publish_time ${record.publishTime}, log_time ${record.logTime}`);
    if (record.sequence !== Number(BigInt(want.sequence) % 2n ** 32n)) fail(`${where}: sequence ${record.sequence}, expected ${want.sequence}`);
    counts[ch.topic] = (counts[ch.topic] ?? 0) + 1;
    if (index % 97 === 0 || index === expected.length - 1) {
      for (const [name, value] of Object.entries(want.fields)) {
        if (!same(decoded[name], value)) fail(`${where}: field ${name} = ${decoded[name]}, expected ${JSON.stringify(value)}`);
      }
      checked += 1;
    }
    index += 1;
  } else if (record.type === "Metadata") {
    metadata = record;
  }
}
if (!reader.done()) fail("the file did not end with a footer");
if (index !== expected.length) fail(`${index} messages, the JSONL has ${expected.length}`);
const wantCounts = {};
for (const w of expected) wantCounts[w.topic] = (wantCounts[w.topic] ?? 0) + 1;
for (const [topic, n] of Object.entries(wantCounts)) {
  if (counts[topic] !== n) fail(`${topic}: ${counts[topic]} messages, expected ${n}`);
}
if (metadata === null || metadata.name !== "eqtrack") fail("no eqtrack metadata record");
console.log(
  `node mcap ${index} messages decoded with CRCs checked; counts per topic equal (${JSON.stringify(counts)}); ` +
    `${checked} sampled messages equal to the project's reading field by field; metadata scenario=${metadata.metadata.get("scenario")}`,
);
