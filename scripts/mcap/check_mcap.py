"""Reads an eqtrack MCAP export with the Python packages `mcap` and `mcap-ros2-support`
(readers no one in this project wrote) and checks it against the project's own reading of
the same messages.log (`eqtrack-export --format jsonl`):

    python check_mcap.py RUN.mcap RUN.jsonl [messages.log]

CRCs are validated; every message is decoded; the message count equals the JSONL's; log_time
never decreases; every decoded field equals the JSONL's value (NaN as NaN). With the run's
messages.log, this script also reads the log itself, with `struct` and the layout that
docs/architecture.md ("The flight recorder") and docs/wire.md document, without the project's
code: the state and cycle channels hold one message per whole record, the command channel one
per record that has a command, and their cycle, time, configuration, velocity, decision,
misses, deadline, arrival time, applied torque, `tau` and Lyapunov value equal the log's bytes.
Prints a summary and exits 1 on the first disagreement.
"""

import json
import math
import os
import struct
import sys

# the flight recorder's layout (format 8) and the wire messages' (protocol 10)
LOG_MAGIC = b"EQTRKLOG"
STATE_AT, COMMAND_AT = 80, 448
GROUP_DIMS = {1: (3, 3), 2: (4, 6), 3: (3, 3)}


def read_log(path):
    """The records of a messages.log, read with the documented offsets only: a list of
    dicts with the fields this script compares."""
    with open(path, "rb") as f:
        data = f.read()
    if data[:8] != LOG_MAGIC:
        sys.exit(f"{path}: not a flight recording")
    version, header_bytes, record_bytes, group = struct.unpack_from("<IIII", data, 8)
    if version != 8:
        sys.exit(f"{path}: format version {version}; this check reads 8")
    n, m = GROUP_DIMS[group]
    records = []
    for at in range(header_bytes, len(data) - record_bytes + 1, record_bytes):
        cycle, decision, has_command = struct.unpack_from("<QBB", data, at)
        misses, deadline, received = struct.unpack_from("<IQQ", data, at + 12)
        applied = list(struct.unpack_from(f"<{m}d", data, at + 32))
        s = at + STATE_AT
        rec = {
            "cycle": cycle,
            "decision": decision,
            "misses_in_row": misses,
            "deadline_ns": deadline,
            "has_command": bool(has_command),
            "received_ns": received,
            "applied": applied,
            "t": struct.unpack_from("<d", data, s + 16)[0],
            "q": list(struct.unpack_from(f"<{n * n}d", data, s + 40)),
            "v": list(struct.unpack_from(f"<{m}d", data, s + 168)),
            "applied_before": list(struct.unpack_from(f"<{m}d", data, s + 216)),
        }
        wheels = struct.unpack_from("<I", data, s + 312)[0]
        rec["wheel_speeds"] = list(struct.unpack_from(f"<{wheels}d", data, s + 320))
        if has_command:
            c = at + COMMAND_AT
            rec["seq"] = struct.unpack_from("<Q", data, c + 8)[0]
            rec["tau"] = list(struct.unpack_from(f"<{m}d", data, c + 40))
            rec["lyapunov"] = struct.unpack_from("<d", data, c + 88)[0]
            actuators, status = struct.unpack_from("<II", data, c + 384)
            rec["actuators"] = actuators
            if actuators > 0:
                rec["alloc_status"] = status
                rec["demand"] = list(struct.unpack_from(f"<{m}d", data, c + 392))
                rec["u_cmd"] = list(struct.unpack_from(f"<{actuators}d", data, c + 632))
            flags = struct.unpack_from("<I", data, c + 304)[0]
            rec["detecting"] = bool(flags & 64)
            rec["supervised"] = bool(flags & 512)
            if rec["supervised"]:
                word = struct.unpack_from("<I", data, c + 380)[0]
                rec.update(
                    action=["nominal", "warn", "hold", "damp", "descend", "surface", "disarm"][word & 0xF],
                    cause=["", "link", "estimator", "actuators", "tracking"][word >> 4 & 0xF],
                    raised=word >> 8 & 0xF, word=word)
            if rec["detecting"]:
                detected, kind, value, refined, alarms = struct.unpack_from("<IIdII", data, c + 728)
                statistic, suspect = struct.unpack_from("<dI", data, c + 752)
                rec.update(detected=detected - 1.0, value=value, alarms=alarms,
                           statistic=statistic, suspect=suspect - 1.0, refined=bool(refined),
                           kind=["", "dead", "stuck", "effectiveness"][kind])
        records.append(rec)
    return records


def check_against_log(log_path, by_topic):
    """Every state, cycle and command message against the log's own bytes."""
    records = read_log(log_path)
    commands = [r for r in records if r["has_command"]]
    checks = (
        ("/eqtrack/state", records, ("cycle", "t", "q", "v", "applied_before", "wheel_speeds")),
        ("/eqtrack/cycle", records, ("cycle", "decision", "misses_in_row", "deadline_ns", "has_command", "received_ns", "applied")),
        ("/eqtrack/command", commands, ("cycle", "seq", "tau", "lyapunov")),
        ("/eqtrack/actuators", [r for r in commands if r["actuators"] > 0], ("cycle", "alloc_status", "demand", "u_cmd")),
        ("/eqtrack/detection", [r for r in commands if r["detecting"]], ("cycle", "suspect", "statistic", "alarms", "detected", "kind", "value", "refined")),
        ("/eqtrack/failsafe", [r for r in commands if r["supervised"]], ("cycle", "action", "cause", "raised", "word")),
    )
    for topic, want, fields in checks:
        got = by_topic.get(topic, [])
        if len(got) != len(want):
            sys.exit(f"{topic}: {len(got)} messages, but {log_path} holds {len(want)} whole records for it")
        for decoded, rec in zip(got, want):
            for name in fields:
                field, value = getattr(decoded, name), rec[name]
                if not same(field, value):
                    sys.exit(f"{topic} cycle {rec['cycle']}: field {name} = {field!r}, but messages.log holds {value!r}")
    return len(records), len(commands)

from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory


def same(decoded, want):
    """`want` is the JSONL value: numbers, lists, or "NaN" / "inf" / "-inf"."""
    if isinstance(want, list):
        decoded = list(decoded)
        return len(decoded) == len(want) and all(same(d, w) for d, w in zip(decoded, want))
    if want == "NaN" or (isinstance(want, float) and math.isnan(want)):
        return isinstance(decoded, float) and math.isnan(decoded)
    if want in ("inf", "-inf"):
        return decoded == float(want)
    if isinstance(want, bool):
        return bool(decoded) == want
    if isinstance(want, float):
        return isinstance(decoded, float) and decoded == want
    return decoded == want


def main(mcap_path, jsonl_path, log_path=None):
    with open(jsonl_path) as f:
        expected = [json.loads(line) for line in f]
    count = 0
    last_time = -1
    topics = {}
    by_topic = {}
    with open(mcap_path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()], validate_crcs=True)
        summary = reader.get_summary()
        metadata = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
        attachments = [a.name for a in reader.iter_attachments()]
        # in file order, which is the export's order
        for schema, channel, message, decoded in reader.iter_decoded_messages(log_time_order=False):
            if count >= len(expected):
                sys.exit(f"more messages in the MCAP than in the JSONL ({len(expected)})")
            want = expected[count]
            where = f"message {count} ({channel.topic}, cycle {want['sequence']})"
            if channel.topic != want["topic"] or schema.name != want["schema"]:
                sys.exit(f"{where}: topic/schema {channel.topic}/{schema.name}, expected {want['topic']}/{want['schema']}")
            if message.log_time < last_time:
                sys.exit(f"{where}: log_time {message.log_time} decreases (after {last_time})")
            last_time = message.log_time
            if message.log_time != want["log_time"] or message.publish_time != want["log_time"]:
                sys.exit(f"{where}: log_time {message.log_time}, expected {want['log_time']}")
            if message.sequence != want["sequence"] % 2**32:
                sys.exit(f"{where}: sequence {message.sequence}, expected {want['sequence']}")
            for name, value in want["fields"].items():
                got = getattr(decoded, name)
                if not same(got, value):
                    sys.exit(f"{where}: field {name} = {got!r}, expected {value!r}")
            topics[channel.topic] = topics.get(channel.topic, 0) + 1
            if log_path is not None and channel.topic in ("/eqtrack/state", "/eqtrack/cycle", "/eqtrack/command", "/eqtrack/actuators", "/eqtrack/detection", "/eqtrack/failsafe"):
                by_topic.setdefault(channel.topic, []).append(decoded)
            count += 1
    if count != len(expected):
        sys.exit(f"{count} messages in the MCAP, {len(expected)} in the JSONL")
    if summary is not None and summary.statistics is not None:
        if summary.statistics.message_count != count:
            sys.exit(f"statistics say {summary.statistics.message_count} messages, read {count}")
    if "eqtrack" not in metadata or "fingerprint" not in metadata["eqtrack"]:
        sys.exit(f"no eqtrack metadata record with the header: {metadata}")
    against_log = ""
    if log_path is not None:
        records, commands = check_against_log(log_path, by_topic)
        engaged = sorted({m.action for m in by_topic.get("/eqtrack/failsafe", []) if m.action != "nominal"})
        against_log = (
            f"; {records} records and {commands} commands of {os.path.basename(log_path)}, read with struct, "
            "equal to the state, cycle, command, actuators, detection and failsafe channels"
            f" (failsafe actions engaged: {engaged or 'none'})"
        )
    print(
        f"python mcap {count} messages decoded with CRCs checked, all equal to the project's reading{against_log}; "
        f"per topic {topics}; metadata run={metadata['eqtrack'].get('run')} "
        f"scenario={metadata['eqtrack'].get('scenario')}; attachments {attachments}"
    )


if __name__ == "__main__":
    if len(sys.argv) not in (3, 4):
        sys.exit(__doc__)
    main(*sys.argv[1:])
