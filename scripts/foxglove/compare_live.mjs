// Compares what a Foxglove client decoded from the live bridge (live_client.mjs's OUT.json)
// with the flight log's export of the same run (`plant_sim export OUT --format jsonl`):
//
//     node compare_live.mjs LIVE.json RUN.jsonl MIN
//
// Each live state and command is matched with the export's message of the same topic and
// `cycle`. Every field must be equal (NaN as NaN), except the command's `received_ns` (the
// plant's receive time, which the bridge cannot know: it sends 0, and that is checked), and
// the log time must be the export's. A live state with no exported counterpart is an
// error (the recorder records every cycle); a live command may have none (a late command is
// not recorded), but at least MIN states and MIN commands must be matched. The status
// channel (not in the export) must have messages with the run's figures. Exits 1 naming the
// first difference.
import { readFileSync } from "node:fs";

const [livePath, jsonlPath, minText] = process.argv.slice(2);
const min = Number(minText);
const live = JSON.parse(readFileSync(livePath, "utf8"));
const fail = (msg) => {
  console.error(`compare (${live.subprotocol}): ${msg}`);
  process.exit(1);
};
const exported = new Map();
for (const line of readFileSync(jsonlPath, "utf8").trim().split("\n")) {
  const m = JSON.parse(line);
  exported.set(`${m.topic} ${m.fields.cycle}`, m);
}

const same = (got, want) => {
  if (Array.isArray(want)) {
    return Array.isArray(got) && got.length === want.length && want.every((w, i) => same(got[i], w));
  }
  if (typeof want === "number" && typeof got === "string" && /^\d+$/.test(got)) return BigInt(got) === BigInt(want);
  if (typeof want === "boolean") return Boolean(got) === want;
  return got === want;
};

if (live.serverInfo?.op !== "serverInfo") fail("no serverInfo");
if (!live.serverInfo.metadata?.run) fail("serverInfo's metadata names no run");
const topics = live.channels.map((c) => c.topic).sort();
for (const t of ["/eqtrack/command", "/eqtrack/state", "/eqtrack/status"]) {
  if (!topics.includes(t)) fail(`${t} was not advertised`);
}
const matched = { "/eqtrack/state": 0, "/eqtrack/command": 0 };
let unmatchedCommands = 0;
let statuses = 0;
for (const m of live.messages) {
  if (m.topic === "/eqtrack/status") {
    statuses += 1;
    if (!(Number(m.fields.rate_hz) >= 0) || m.fields.scenario === "") fail(`a status without the run's figures: ${JSON.stringify(m.fields)}`);
    continue;
  }
  const want = exported.get(`${m.topic} ${m.fields.cycle}`);
  const where = `${m.topic} at cycle ${m.fields.cycle}`;
  if (want === undefined) {
    if (m.topic === "/eqtrack/state") fail(`${where}: no such message in the export`);
    unmatchedCommands += 1;
    continue;
  }
  if (m.log_time !== String(want.log_time)) fail(`${where}: log time ${m.log_time}, the export's ${want.log_time}`);
  const names = Object.keys(want.fields);
  if (Object.keys(m.fields).sort().join() !== [...names].sort().join()) fail(`${where}: fields ${Object.keys(m.fields)}, the export's ${names}`);
  for (const name of names) {
    if (m.topic === "/eqtrack/command" && name === "received_ns") {
      if (m.fields[name] !== "0") fail(`${where}: received_ns ${m.fields[name]}, the bridge's is 0`);
      continue;
    }
    if (!same(m.fields[name], want.fields[name])) {
      fail(`${where}: field ${name} = ${JSON.stringify(m.fields[name])} differs from the export's ${JSON.stringify(want.fields[name])}`);
    }
  }
  matched[m.topic] += 1;
}
for (const [topic, n] of Object.entries(matched)) {
  if (n < min) fail(`only ${n} ${topic} messages matched the export (at least ${min} wanted)`);
}
if (statuses === 0) fail("no status message");
if (!live.statuses.some((s) => /ended at cycle/.test(s.message))) fail(`no "run ended" status; got ${JSON.stringify(live.statuses)}`);
console.log(
  `compare (${live.subprotocol}): ${matched["/eqtrack/state"]} states and ${matched["/eqtrack/command"]} commands equal to the export field by field ` +
    `(${unmatchedCommands} commands not recorded), ${statuses} status messages, the run's end announced`,
);
