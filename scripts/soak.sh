#!/usr/bin/env bash
# Soak: the pair for 10^6 cycles at 10 kHz (busy poll) and at 1 kHz (event), sampling both
# processes' resident memory and open file descriptors once a second. Not part of CI (the
# 1 kHz leg alone takes 17 minutes).
#
#   cargo build --release -p plant_sim -p controller_node
#   bash scripts/soak.sh [CYCLES]          # default 1000000; outputs in out/soak-*/
#
# Each leg writes out/soak-<rate>hz/{resources.csv, summary.json, trajectory.csv (every
# 1000th cycle), ...} and prints, per process, the resident set and descriptor count at the
# start of the loop and at the end, and the growth per 10^5 cycles (least-squares slope over
# the loop's second half, so start-up is not counted as growth).
set -euo pipefail
REPO=$(cd -- "$(dirname -- "${BASH_SOURCE[0]}")/.." && pwd)
BIN=${BIN:-$REPO/target/release}
CYCLES=${1:-1000000}
[[ -x $BIN/plant_sim && -x $BIN/controller_node ]] ||
	{ echo "soak: build first: cargo build --release -p plant_sim -p controller_node" >&2; exit 1; }

sample() { # pid -> "rss_kb fds"
	local rss fds
	rss=$(awk '/^VmRSS:/ {print $2}' "/proc/$1/status" 2>/dev/null || echo "")
	fds=$(ls "/proc/$1/fd" 2>/dev/null | wc -l)
	echo "${rss:-NA} $fds"
}

leg() { # rate wake
	local rate=$1 wake=$2 out=$REPO/out/soak-${1}hz run=soak-$1
	local seconds
	seconds=$(python3 -c "print($CYCLES / $rate)")
	mkdir -p "$out"
	echo "soak: $CYCLES cycles at $rate Hz ($wake wake-up): $seconds s" >&2
	"$BIN/controller_node" --name "$run" --startup-timeout 60 2>"$out/controller.log" &
	local ctl=$!
	"$BIN/plant_sim" run --no-spawn --name "$run" --rate-hz "$rate" --wake "$wake" \
		--duration "$seconds" --record-every 1000 --out "$out" >"$out/plant.log" 2>&1 &
	local plant=$!
	echo "t_s,plant_rss_kb,plant_fds,controller_rss_kb,controller_fds" >"$out/resources.csv"
	local t0=$SECONDS
	while kill -0 "$plant" 2>/dev/null; do
		read -r prss pfds <<<"$(sample "$plant")"
		read -r crss cfds <<<"$(sample "$ctl")"
		[[ $prss != NA && $crss != NA ]] && echo "$((SECONDS - t0)),$prss,$pfds,$crss,$cfds" >>"$out/resources.csv"
		sleep 1
	done
	wait "$plant" || { tail -5 "$out/plant.log" >&2; echo "soak: the plant failed" >&2; exit 1; }
	wait "$ctl" || true
	python3 - "$out/resources.csv" "$rate" <<'PY'
import csv, sys
rows = [r for r in csv.DictReader(open(sys.argv[1]))]
rate = float(sys.argv[2])
if len(rows) > 6:
    rows = rows[2:]  # the loop, after start-up
if len(rows) < 2:
    sys.exit("soak: too few samples (run more cycles)")
half = rows[len(rows) // 2:]
for who in ("plant", "controller"):
    for what, unit in (("rss_kb", "KiB"), ("fds", "fds")):
        key = f"{who}_{what}"
        xs = [float(r["t_s"]) for r in half]
        ys = [float(r[key]) for r in half]
        n = len(xs)
        mx, my = sum(xs) / n, sum(ys) / n
        sxx = sum((x - mx) ** 2 for x in xs) or 1.0
        slope = sum((x - mx) * (y - my) for x, y in zip(xs, ys)) / sxx  # per second
        per_1e5 = slope * 1e5 / rate
        print(f"  {who:<10} {what:<6}: start {rows[0][key]:>7} end {rows[-1][key]:>7} "
              f"max {max(float(r[key]) for r in rows):>9.0f} {unit}; "
              f"growth {per_1e5:+.2f} {unit} per 1e5 cycles")
PY
	grep -hE "^deadline misses|heap allocations after" "$out/plant.log" "$out/controller.log" | sed "s/^/  /" || true
}

leg 10000 spin
leg 1000 event
