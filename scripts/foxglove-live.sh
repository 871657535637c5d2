#!/usr/bin/env bash
# The live Foxglove bridge read by a client no one in this project wrote (docs/live.md):
# npm's @foxglove/ws-protocol FoxgloveClient over the `ws` package, decoding with
# @foxglove/rosmsg and @foxglove/rosmsg2-serialization (the libraries Foxglove's app decodes
# with), under Node (scripts/foxglove/live_client.mjs).
#
#   scripts/foxglove-live.sh
#
#  1. `plant_sim live --name RUN` starts, and two clients connect to it, one offering the
#     subprotocol `foxglove.websocket.v1` (FoxgloveClient's own), the other
#     `foxglove.sdk.v1` (Foxglove's app's); each subscribes to /eqtrack/state,
#     /eqtrack/command and /eqtrack/status;
#  2. a real-time pair flies 3 s at 1 kHz under that name (`plant_sim run --rate-hz 1000`);
#  3. at the run's end the bridge announces it and closes, and exits 0;
#  4. each client's decoded messages are compared with the flight log's export of the same
#     run (`plant_sim export --format jsonl`), matched by cycle: every field equal except the
#     command's received_ns (0 live), the same log time, at least 100 states and 100 commands
#     matched (scripts/foxglove/compare_live.mjs);
#  5. the comparison must fail on a planted difference (a state's `v` changed in a copy of
#     the export) and on a count it cannot reach.
#
# The packages are pinned (NODE_PACKAGES below) and cached in <repo>/.toolchain/foxglove-node
# (TOOLCHAIN_CACHE overrides); a cache of other versions is installed anew. Prints one
# `SKIPPED: <reason>` line, and exits 0, only when node or npm is missing or npm cannot
# install the packages; packages that install but do not import, and anything else that
# fails, fail the script (exit 1).
set -euo pipefail
REPO=$(cd -- "$(dirname -- "${BASH_SOURCE[0]}")/.." && pwd)
CACHE=${TOOLCHAIN_CACHE:-$REPO/.toolchain}
NODE=$CACHE/foxglove-node
OUT=$CACHE/foxglove-live
NODE_PACKAGES="@foxglove/ws-protocol@0.8.0 ws@8.23.0 @foxglove/rosmsg@5.0.5 @foxglove/rosmsg2-serialization@3.1.0"
RUN=fglive-$$
PIDS=()
die() {
	echo "foxglove-live: FAIL: $*" >&2
	exit 1
}
cleanup() {
	local p
	for p in "${PIDS[@]}"; do kill "$p" 2>/dev/null || true; done
}
trap cleanup EXIT
mkdir -p "$CACHE" "$OUT" "$NODE"
[[ -f $CACHE/.gitignore ]] || printf '*\n' >"$CACHE/.gitignore"

if ! command -v node >/dev/null || ! command -v npm >/dev/null; then
	echo "SKIPPED: node and npm are not installed"
	exit 0
fi
if [[ $(cat "$NODE/.pinned" 2>/dev/null) != "$NODE_PACKAGES" ]]; then
	rm -rf "$NODE/node_modules" "$NODE/package.json" "$NODE/package-lock.json" "$NODE/.pinned"
	if (cd "$NODE" && npm init -y >/dev/null 2>&1 &&
		npm install --no-audit --no-fund --loglevel=error $NODE_PACKAGES >"$OUT/npm.log" 2>&1); then
		echo "$NODE_PACKAGES" >"$NODE/.pinned"
	else
		echo "SKIPPED: npm could not install $NODE_PACKAGES: $(grep -m1 -E 'ERR|error (code|network|request)|ECONN' "$OUT/npm.log" || head -1 "$OUT/npm.log")"
		exit 0
	fi
fi
cp "$REPO/scripts/foxglove/live_client.mjs" "$REPO/scripts/foxglove/compare_live.mjs" "$NODE/"
(cd "$NODE" && node --input-type=module -e '
import "@foxglove/ws-protocol"; import "@foxglove/rosmsg"; import "@foxglove/rosmsg2-serialization"; import "ws";') ||
	die "$NODE_PACKAGES installed but do not import"

TARGET=$(cd "$REPO" && cargo metadata --format-version 1 --no-deps |
	python3 -c 'import json, sys; print(json.load(sys.stdin)["target_directory"])')
BIN=$TARGET/debug
[[ -x $BIN/plant_sim && -x $BIN/controller_node && -x $BIN/eqtrack-export && -x $BIN/eqtrack-live ]] ||
	(cd "$REPO" && cargo build --locked -p plant_sim -p controller_node -p export -p live >"$OUT/build.log" 2>&1) ||
	die "cannot build plant_sim, controller_node, eqtrack-export and eqtrack-live (log: $OUT/build.log)"

# wait_for FILE TEXT SECONDS PID: until FILE holds TEXT; fails after SECONDS or when PID is gone
wait_for() {
	local i
	for ((i = 0; i < $3 * 10; i++)); do
		grep -q -- "$2" "$1" 2>/dev/null && return 0
		kill -0 "$4" 2>/dev/null || return 1
		sleep 0.1
	done
	return 1
}

rm -rf "$OUT/run" "$OUT"/*.json "$OUT"/*.log
PORT=$(python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
"$BIN/plant_sim" live --name "$RUN" --listen "127.0.0.1:$PORT" --wait 60 >"$OUT/live.log" 2>&1 &
LIVE=$!
PIDS+=("$LIVE")
wait_for "$OUT/live.log" "serving run" 30 "$LIVE" || die "the bridge did not start: $(tail -3 "$OUT/live.log")"
CLIENTS=()
for proto in foxglove.websocket.v1 foxglove.sdk.v1; do
	(cd "$NODE" && exec node live_client.mjs "ws://127.0.0.1:$PORT" "$proto" "$OUT/$proto.json") >"$OUT/client-$proto.log" 2>&1 &
	CLIENTS+=($!)
	PIDS+=($!)
	wait_for "$OUT/client-$proto.log" "^subscribed" 30 "${CLIENTS[-1]}" || die "the $proto client did not subscribe: $(tail -3 "$OUT/client-$proto.log")"
done
"$BIN/plant_sim" run --rate-hz 1000 --duration 3 --name "$RUN" --out "$OUT/run" >"$OUT/plant.log" 2>&1 ||
	die "the run failed: $(tail -3 "$OUT/plant.log")"
rc=0
wait "$LIVE" || rc=$?
((rc == 0)) || die "the bridge exited $rc at the run's end: $(tail -3 "$OUT/live.log")"
grep "live: " "$OUT/live.log" | tail -2
for i in "${!CLIENTS[@]}"; do
	wait "${CLIENTS[$i]}" || die "a client failed: $(cat "$OUT"/client-*.log | tail -4)"
done
"$BIN/plant_sim" export "$OUT/run" --format jsonl >/dev/null || die "the export of $OUT/run failed"
for proto in foxglove.websocket.v1 foxglove.sdk.v1; do
	(cd "$NODE" && node compare_live.mjs "$OUT/$proto.json" "$OUT/run/run.jsonl" 100) ||
		die "the live messages ($proto) differ from the export"
done

# the comparison can fail: a planted difference, and a count it cannot reach
python3 - "$OUT/run/run.jsonl" "$OUT/planted.jsonl" <<'PY'
import json, sys
with open(sys.argv[1]) as f, open(sys.argv[2], "w") as out:
    for line in f:
        m = json.loads(line)
        if m["topic"] == "/eqtrack/state":
            m["fields"]["v"][0] = m["fields"]["v"][0] + 1e-9 if isinstance(m["fields"]["v"][0], float) else 1.0
        out.write(json.dumps(m) + "\n")
PY
if why=$(cd "$NODE" && node compare_live.mjs "$OUT/foxglove.websocket.v1.json" "$OUT/planted.jsonl" 100 2>&1); then
	die "the comparison passed with a planted difference in every state: it cannot fail"
fi
grep -q "field v = .* differs from the export's" <<<"$why" || die "the planted difference failed for another reason: $why"
echo "foxglove-live: the comparison catches a planted difference: $why"
if why=$(cd "$NODE" && node compare_live.mjs "$OUT/foxglove.websocket.v1.json" "$OUT/run/run.jsonl" 100000000 2>&1); then
	die "the comparison passed with an impossible count"
fi
grep -q "only .* matched the export" <<<"$why" || die "the impossible count failed for another reason: $why"
echo "foxglove-live: PASS"
