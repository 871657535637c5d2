#!/usr/bin/env bash
# The MCAP export read by libraries no one in this project wrote, as Foxglove's users and
# PlotJuggler's would read it:
#   (a) Python: a venv with `mcap` and `mcap-ros2-support` (scripts/mcap/check_mcap.py): CRCs
#       validated, every message decoded, count = the records' messages, log_time never
#       decreasing, every decoded value equal to the project's own reading of messages.log
#       (`plant_sim export --format jsonl`), NaN as NaN;
#   (b) Node: `@mcap/core`, `@foxglove/rosmsg` and `@foxglove/rosmsg2-serialization`, the
#       libraries Foxglove's app decodes with (scripts/mcap/check_mcap.mjs): the same counts
#       and a sample of values.
# Three runs, so every channel is there: the observer's set-point (`scenarios/reject_so3.toml`,
# 4 s in lockstep: the disturbance terms), the SE(3) equivariant filter (`eqf_se3.toml`, 2 s:
# sensor samples and estimates) and `slew_so3.toml` streamed by the planner (plan messages).
#
#   scripts/mcap-readers.sh
#
# Packages are cached in <repo>/.toolchain/{mcap-venv,mcap-node} (TOOLCHAIN_CACHE
# overrides). Each reader prints one `SKIPPED: <reason>` line where its packages cannot be
# installed, and the other still runs. Exit 1 on any disagreement.
set -euo pipefail
REPO=$(cd -- "$(dirname -- "${BASH_SOURCE[0]}")/.." && pwd)
CACHE=${TOOLCHAIN_CACHE:-$REPO/.toolchain}
VENV=$CACHE/mcap-venv
NODE=$CACHE/mcap-node
OUT=$CACHE/mcap-readers
die() {
	echo "mcap-readers: FAIL: $*" >&2
	exit 1
}
mkdir -p "$CACHE" "$OUT" "$NODE"
[[ -f $CACHE/.gitignore ]] || printf '*\n' >"$CACHE/.gitignore"

TARGET=$(cd "$REPO" && cargo metadata --format-version 1 --no-deps |
	python3 -c 'import json, sys; print(json.load(sys.stdin)["target_directory"])')
BIN=$TARGET/debug
[[ -x $BIN/plant_sim && -x $BIN/controller_node && -x $BIN/eqtrack-export && -x $BIN/planner ]] ||
	(cd "$REPO" && cargo build --locked -p plant_sim -p controller_node -p export -p examples >"$OUT/build.log" 2>&1) ||
	die "cannot build plant_sim, controller_node, planner and eqtrack-export (log: $OUT/build.log)"

# export DIR to run.mcap and run.jsonl
export_run() {
	"$BIN/plant_sim" export "$1" || die "export of $1 to MCAP failed"
	"$BIN/plant_sim" export "$1" --format jsonl >/dev/null || die "export of $1 to JSONL failed"
}
RUNS=()
rm -rf "$OUT/run" "$OUT/eqf" "$OUT/stream"
"$BIN/plant_sim" run --scenario "$REPO/scenarios/reject_so3.toml" --mode lockstep --duration 4 \
	--name "mcap-$$" --out "$OUT/run" >"$OUT/plant.log" 2>&1 || die "the run failed: $(tail -3 "$OUT/plant.log")"
RUNS+=("$OUT/run")
"$BIN/plant_sim" run --scenario "$REPO/scenarios/eqf_se3.toml" --mode lockstep --duration 2 \
	--name "mcap-eqf-$$" --out "$OUT/eqf" >"$OUT/plant-eqf.log" 2>&1 || die "the EqF run failed: $(tail -3 "$OUT/plant-eqf.log")"
RUNS+=("$OUT/eqf")
# streamed: the planner publishes the whole path, the controller takes it from the plan board
SLEW=$REPO/scenarios/slew_so3.toml
"$BIN/planner" --scenario "$SLEW" --name "mcap-st-$$" --horizon 1000 >"$OUT/planner.log" 2>&1 &
PLANNER=$!
for _ in $(seq 100); do grep -q "published pieces" "$OUT/planner.log" && break; sleep 0.1; done
"$BIN/controller_node" --scenario "$SLEW" --name "mcap-st-$$" --reference stream >"$OUT/ctl.log" 2>&1 &
CTL=$!
"$BIN/plant_sim" run --scenario "$SLEW" --mode lockstep --no-spawn --name "mcap-st-$$" --out "$OUT/stream" \
	>"$OUT/plant-stream.log" 2>&1 || { kill $PLANNER $CTL 2>/dev/null; die "the streamed run failed: $(tail -3 "$OUT/plant-stream.log")"; }
wait $PLANNER $CTL || die "the planner or the controller failed: $(tail -2 "$OUT/planner.log" "$OUT/ctl.log")"
[[ -s $OUT/stream/plans.log ]] || die "the streamed run recorded no plan messages"
RUNS+=("$OUT/stream")
for run in "${RUNS[@]}"; do export_run "$run"; done

# (a) Python
if ! "$VENV/bin/python" -c "import mcap, mcap_ros2" 2>/dev/null; then
	rm -rf "$VENV"
	if ! python3 -m venv "$VENV" >"$OUT/venv.log" 2>&1; then
		echo "SKIPPED: python3 -m venv failed: $(tail -1 "$OUT/venv.log")"
	elif ! "$VENV/bin/pip" install -q mcap mcap-ros2-support >"$OUT/pip.log" 2>&1; then
		echo "SKIPPED: pip could not install mcap and mcap-ros2-support: $(grep -m1 -E 'ERROR' "$OUT/pip.log" || tail -1 "$OUT/pip.log")"
	fi
fi
if "$VENV/bin/python" -c "import mcap, mcap_ros2" 2>/dev/null; then
	for run in "${RUNS[@]}"; do
		"$VENV/bin/python" "$REPO/scripts/mcap/check_mcap.py" "$run/run.mcap" "$run/run.jsonl" ||
			die "the Python reader disagrees on $run"
	done
fi

# (b) Node
if ! command -v node >/dev/null || ! command -v npm >/dev/null; then
	echo "SKIPPED: node and npm are not installed"
else
	if [[ ! -d $NODE/node_modules/@foxglove/rosmsg2-serialization ]]; then
		(cd "$NODE" && { [[ -f package.json ]] || npm init -y >/dev/null 2>&1; } &&
			npm install --silent --no-audit --no-fund @mcap/core @foxglove/rosmsg @foxglove/rosmsg2-serialization \
				>"$OUT/npm.log" 2>&1) ||
			echo "SKIPPED: npm could not install @mcap/core and @foxglove/rosmsg2-serialization: $(tail -1 "$OUT/npm.log")"
	fi
	if [[ -d $NODE/node_modules/@foxglove/rosmsg2-serialization ]]; then
		cp "$REPO/scripts/mcap/check_mcap.mjs" "$NODE/check_mcap.mjs"
		for run in "${RUNS[@]}"; do
			(cd "$NODE" && node check_mcap.mjs "$run/run.mcap" "$run/run.jsonl") || die "the Node reader disagrees on $run"
		done
	fi
fi
echo "mcap-readers: PASS"
