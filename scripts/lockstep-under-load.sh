#!/usr/bin/env bash
# Lockstep is exact whatever the machine is doing: with a CPU hog on every core
# (scripts/under-load.sh), each scenario below is flown by `plant_sim sim` and twice by the
# lockstep pair, and the files must be equal byte for byte:
#   * trajectory.csv of both lockstep runs = the simulation's;
#   * messages.log of the second lockstep run = the first's (a lockstep log holds no clock
#     reading and no process id: docs/architecture.md, "A lockstep log is reproducible").
# Scenarios: seed, se3_circle, reject_so3, sensors_so3 (complementary filter), eqf_so3 (the
# EqF), and slew_so3 streamed by the planner example to `controller_node --reference stream`.
#
#   cargo test --workspace            # builds target/debug/{plant_sim,controller_node,planner}
#   bash scripts/lockstep-under-load.sh
#
# Environment: BIN (default: the cargo target directory's debug), OUT (default: a temporary
# directory, removed at the end), HOG=0 runs without the hog.
set -euo pipefail
REPO=$(cd -- "$(dirname -- "${BASH_SOURCE[0]}")/.." && pwd)
BIN=${BIN:-$REPO/target/debug}
die() {
	echo "lockstep-under-load: FAIL: $*" >&2
	exit 1
}
for b in plant_sim controller_node planner; do
	[[ -x $BIN/$b ]] || die "$BIN/$b is missing: run cargo test --workspace first (it builds the binaries)"
done
if [[ -z ${OUT:-} ]]; then
	OUT=$(mktemp -d)
	trap 'rm -rf "$OUT"' EXIT
fi
mkdir -p "$OUT"

if [[ ${HOG:-1} != 0 && -z ${UNDER_LOAD:-} ]]; then
	UNDER_LOAD=1 exec bash "$REPO/scripts/under-load.sh" bash "$0" "$@"
fi

# one lockstep run of scenario file $1 into $2 under run name $3
lockstep() {
	"$BIN/plant_sim" run --scenario "$1" --mode lockstep --name "$3" --out "$2" >"$2.txt" 2>&1 ||
		die "lockstep run of $1 failed:$(printf '\n')$(cat "$2.txt")"
}

# the same, its reference streamed by the planner (every piece out before the first state)
streamed() {
	local planner ctl code=0
	"$BIN/planner" --scenario "$1" --name "$3" --horizon 1000 >"$2.planner.txt" 2>&1 &
	planner=$!
	for _ in $(seq 2000); do
		grep -q "published pieces" "$2.planner.txt" && break
		sleep 0.01
	done
	grep -q "published pieces" "$2.planner.txt" || die "the planner did not publish: $(cat "$2.planner.txt")"
	"$BIN/controller_node" --scenario "$1" --name "$3" --reference stream >"$2.ctl.txt" 2>&1 &
	ctl=$!
	"$BIN/plant_sim" run --scenario "$1" --mode lockstep --no-spawn --name "$3" --out "$2" >"$2.txt" 2>&1 || code=$?
	wait "$ctl" || die "controller_node failed: $(cat "$2.ctl.txt")"
	wait "$planner" || die "the planner failed: $(cat "$2.planner.txt")"
	[[ $code == 0 ]] || die "streamed lockstep run of $1 failed: $(cat "$2.txt")"
}

same() {
	cmp -s "$1" "$2" || die "$3: $1 and $2 differ ($(cmp "$1" "$2" 2>&1 | head -1))"
}

cases=(seed se3_circle reject_so3 sensors_so3 eqf_so3 slew_so3:stream)
for c in "${cases[@]}"; do
	name=${c%%:*}
	how=lockstep
	[[ $c == *:stream ]] && how=streamed
	file=$REPO/scenarios/$name.toml
	d=$OUT/$name
	mkdir -p "$d"
	start=$SECONDS
	"$BIN/plant_sim" sim --scenario "$file" --out "$d/sim" >"$d/sim.txt" 2>&1 || die "sim $name: $(cat "$d/sim.txt")"
	"$how" "$file" "$d/a" "t-uload-$name"
	"$how" "$file" "$d/b" "t-uload-$name"
	same "$d/sim/trajectory.csv" "$d/a/trajectory.csv" "$name ($how): trajectory.csv of the simulation and of the lockstep run"
	same "$d/a/trajectory.csv" "$d/b/trajectory.csv" "$name ($how): trajectory.csv of two lockstep runs"
	same "$d/a/messages.log" "$d/b/messages.log" "$name ($how): messages.log of two lockstep runs"
	grep -q '"deadline_note"' "$d/a/summary.json" || die "$name: the lockstep summary has no deadline note"
	rows=$(($(wc -l <"$d/a/trajectory.csv") - 1))
	printf 'lockstep-under-load: %-12s %-9s %6d rows, trajectory.csv = sim, messages.log = second run (%ds)\n' \
		"$name" "$how" "$rows" $((SECONDS - start))
done
echo "lockstep-under-load: PASS"
