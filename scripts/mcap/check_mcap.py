"""Reads an eqtrack MCAP export with the Python packages `mcap` and `mcap-ros2-support`
(readers no one in this project wrote) and checks it against the project's own reading of
the same messages.log (`eqtrack-export --format jsonl`):

    python check_mcap.py RUN.mcap RUN.jsonl

CRCs are validated; every message is decoded; the message count equals the JSONL's; log_time
never decreases; every decoded field equals the JSONL's value (NaN as NaN). Prints a summary
and exits 1 on the first disagreement.
"""

import json
import math
import sys

from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory


def same(decoded, want):
    """`want` is the JSONL value: numbers, lists, or "NaN" / "inf" / "-inf"."""
    if isinstance(want, list):
        decoded = list(decoded)
        return len(decoded) == len(want) and all(same(d, w) for d, w in zip(decoded, want))
    if want == "NaN":
        return isinstance(decoded, float) and math.isnan(decoded)
    if want in ("inf", "-inf"):
        return decoded == float(want)
    if isinstance(want, bool):
        return bool(decoded) == want
    if isinstance(want, float):
        return isinstance(decoded, float) and decoded == want
    return decoded == want


def main(mcap_path, jsonl_path):
    with open(jsonl_path) as f:
        expected = [json.loads(line) for line in f]
    count = 0
    last_time = -1
    topics = {}
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
            count += 1
    if count != len(expected):
        sys.exit(f"{count} messages in the MCAP, {len(expected)} in the JSONL")
    if summary is not None and summary.statistics is not None:
        if summary.statistics.message_count != count:
            sys.exit(f"statistics say {summary.statistics.message_count} messages, read {count}")
    if "eqtrack" not in metadata or "fingerprint" not in metadata["eqtrack"]:
        sys.exit(f"no eqtrack metadata record with the header: {metadata}")
    print(
        f"python mcap {count} messages decoded with CRCs checked, all equal to the project's reading; "
        f"per topic {topics}; metadata run={metadata['eqtrack'].get('run')} "
        f"scenario={metadata['eqtrack'].get('scenario')}; attachments {attachments}"
    )


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
