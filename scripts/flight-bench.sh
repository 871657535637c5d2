#!/usr/bin/env bash
# The flight recorder's and the monitor's cost to the loop, measured in one sitting: the same
# real-time run (seed, 1 kHz, event wake-up) without recording (--no-record), with recording
# (the default), and with recording and `plant_sim monitor` attached in a real terminal
# (tmux), interleaved over several rounds so that the machine's drift hits all three alike.
#
#   scripts/flight-bench.sh [ROUNDS] [SECONDS] [RATE_HZ]     # default 3 rounds of 10 s at 1000 Hz
#
# Uses target/release (build it first: cargo build --release --workspace). Prints a Markdown
# table per round and the medians over rounds of each figure; the run directories stay in
# out/flight-bench/.
set -euo pipefail
REPO=$(cd -- "$(dirname -- "${BASH_SOURCE[0]}")/.." && pwd)
ROUNDS=${1:-3}
SECS=${2:-10}
RATE=${3:-1000}
BIN=$REPO/target/release
OUT=$REPO/out/flight-bench
[[ -x $BIN/plant_sim && -x $BIN/controller_node ]] || {
	echo "build first: cargo build --release --workspace" >&2
	exit 1
}
TMUX_BIN=$(bash "$REPO/scripts/tmux.sh" | tail -1)
[[ $TMUX_BIN != SKIPPED* ]] || {
	echo "$TMUX_BIN" >&2
	exit 1
}
SOCK=eqtrack-flight-bench-$$
trap '"$TMUX_BIN" -L "$SOCK" kill-server 2>/dev/null || true' EXIT
rm -rf "$OUT"
mkdir -p "$OUT"

run() { # case round
	local dir=$OUT/$1-$2 name=fb-$1-$2 extra=()
	[[ $1 == no-record ]] && extra=(--no-record)
	if [[ $1 == monitored ]]; then
		"$TMUX_BIN" -L "$SOCK" new-session -d -s "$name" -x 120 -y 32 \
			"$BIN/plant_sim monitor --name $name --wait 30"
	fi
	"$BIN/plant_sim" run --name "$name" --duration "$SECS" --rate-hz "$RATE" --out "$dir" "${extra[@]}" >/dev/null 2>"$dir.log" ||
		{ cat "$dir.log" >&2; exit 1; }
	if [[ $1 == monitored ]]; then
		# the monitor must have been attached and seen the run end
		sleep 0.5
		if "$TMUX_BIN" -L "$SOCK" has-session -t "$name" 2>/dev/null; then
			echo "the monitor of $name is still running after the run ended" >&2
			exit 1
		fi
	fi
}

for r in $(seq 1 "$ROUNDS"); do
	for c in no-record recorded monitored; do
		echo "round $r: $c ($SECS s at $RATE Hz) ..." >&2
		run "$c" "$r"
	done
done

python3 - "$OUT" "$ROUNDS" <<'PY'
import json, statistics, sys
out, rounds = sys.argv[1], int(sys.argv[2])
cases = ["no-record", "recorded", "monitored"]
keys = [("p50_us", "p50"), ("p99_us", "p99"), ("p99_9_us", "p99.9"), ("max_us", "max")]
rows = {c: [] for c in cases}
for r in range(1, rounds + 1):
    for c in cases:
        s = json.load(open(f"{out}/{c}-{r}/summary.json"))
        rows[c].append(s)
print("| case | round | round trip p50 / p99 / p99.9 / max (µs) | misses | plant loop allocations | records |")
print("|---|---|---|---|---|---|")
for r in range(rounds):
    for c in cases:
        s = rows[c][r]
        l = s["latency"]
        rec = s["recording"]["records"] if s["recording"] else "-"
        print(f"| {c} | {r+1} | " + " / ".join(f"{l[k]:.1f}" for k, _ in keys)
              + f" | {s['deadline_misses']} | {s['plant_loop_heap_allocations']} | {rec} |")
print()
print("| case | median over rounds: p50 / p99 / p99.9 / max (µs) | misses |")
print("|---|---|---|")
for c in cases:
    med = [statistics.median(s["latency"][k] for s in rows[c]) for k, _ in keys]
    m = statistics.median(s["deadline_misses"] for s in rows[c])
    print(f"| {c} | " + " / ".join(f"{x:.1f}" for x in med) + f" | {m:g} |")
PY
