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
# The Python reader also reads each messages.log itself with `struct` and the documented
# layout, and checks the state, cycle and command channels against it record by record; the
# figure script of docs/flight-recorder.md, "Looking at a run in Foxglove or PlotJuggler"
# (scripts/mcap/plot_mcap.py), then draws the first run from its MCAP.
# Four runs, so every channel is there: the observer's set-point (`scenarios/reject_so3.toml`,
# 4 s in lockstep: the disturbance terms), the SE(3) equivariant filter (`eqf_se3.toml`, 2 s:
# sensor samples, estimates, covariance), the complementary filter (`sensors_so3.toml`, 2 s:
# its NEES is NaN in every estimate message) and `slew_so3.toml` streamed by the planner
# (plan messages); then vehicles: `rov_failure.toml` (actuators) and `pil_rov_surface.toml`
# (the failure detector, and the failsafe manager with `surface` engaged).
#
#   scripts/mcap-readers.sh
#
# The packages are pinned (PY_PACKAGES, NODE_PACKAGES below) and cached in
# <repo>/.toolchain/{mcap-venv,mcap-node} (TOOLCHAIN_CACHE overrides); a cache of other
# versions is installed anew. Each reader prints one `SKIPPED: <reason>` line where its
# packages cannot be installed, and the other still runs; packages that install but do not
# import fail the script. Exit 1 on any disagreement.
set -euo pipefail
REPO=$(cd -- "$(dirname -- "${BASH_SOURCE[0]}")/.." && pwd)
CACHE=${TOOLCHAIN_CACHE:-$REPO/.toolchain}
VENV=$CACHE/mcap-venv
NODE=$CACHE/mcap-node
OUT=$CACHE/mcap-readers
PY_PACKAGES="mcap==1.6.0 mcap-ros2-support==0.6.0 matplotlib==3.11.2"
NODE_PACKAGES="@mcap/core@2.2.2 @foxglove/rosmsg@5.0.5 @foxglove/rosmsg2-serialization@3.1.0"
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
rm -rf "$OUT/run" "$OUT/eqf" "$OUT/cf" "$OUT/stream"
"$BIN/plant_sim" run --scenario "$REPO/scenarios/reject_so3.toml" --mode lockstep --duration 4 \
	--name "mcap-$$" --out "$OUT/run" >"$OUT/plant.log" 2>&1 || die "the run failed: $(tail -3 "$OUT/plant.log")"
RUNS+=("$OUT/run")
"$BIN/plant_sim" run --scenario "$REPO/scenarios/eqf_se3.toml" --mode lockstep --duration 2 \
	--name "mcap-eqf-$$" --out "$OUT/eqf" >"$OUT/plant-eqf.log" 2>&1 || die "the EqF run failed: $(tail -3 "$OUT/plant-eqf.log")"
RUNS+=("$OUT/eqf")
"$BIN/plant_sim" run --scenario "$REPO/scenarios/sensors_so3.toml" --mode lockstep --duration 2 \
	--name "mcap-cf-$$" --out "$OUT/cf" >"$OUT/plant-cf.log" 2>&1 || die "the complementary-filter run failed: $(tail -3 "$OUT/plant-cf.log")"
RUNS+=("$OUT/cf")
"$BIN/plant_sim" run --scenario "$REPO/scenarios/rov_failure.toml" --mode lockstep --duration 2 \
	--name "mcap-rov-$$" --out "$OUT/rov" >"$OUT/plant-rov.log" 2>&1 || die "the vehicle run failed: $(tail -3 "$OUT/plant-rov.log")"
RUNS+=("$OUT/rov")
# reaction wheels: the state channel carries their four speeds
"$BIN/plant_sim" run --scenario "$REPO/scenarios/wheels_slew.toml" --mode lockstep --duration 2 \
	--name "mcap-wheels-$$" --out "$OUT/wheels" >"$OUT/plant-wheels.log" 2>&1 || die "the wheels run failed: $(tail -3 "$OUT/plant-wheels.log")"
RUNS+=("$OUT/wheels")
# the failure detector's and the failsafe manager's channels: pil_rov_surface's ROV in a current
# loses horizontal thrusters 1 and 2 unannounced; the detector finds both (1.47 s, 2.57 s) and
# the manager engages `surface` when the thrusters left no longer push every way (2.57 s)
"$BIN/plant_sim" run --scenario "$REPO/scenarios/pil_rov_surface.toml" --mode lockstep \
	--name "mcap-det-$$" --out "$OUT/detect" >"$OUT/plant-detect.log" 2>&1 || die "the detector's run failed: $(tail -3 "$OUT/plant-detect.log")"
grep -q "actuator 1 dead" "$OUT/plant-detect.log" || die "the detector's run found nothing: $(tail -3 "$OUT/plant-detect.log")"
grep -q "actuators → surface" "$OUT/plant-detect.log" || die "the failsafe manager did not engage: $(tail -3 "$OUT/plant-detect.log")"
RUNS+=("$OUT/detect")
# streamed: the planner publishes the whole path, the controller takes it from the plan board
SLEW=$REPO/scenarios/slew_so3.toml
"$BIN/planner" --scenario "$SLEW" --name "mcap-st-$$" --horizon 1000 >"$OUT/planner.log" 2>&1 &
PLANNER=$!
for _ in $(seq 100); do grep -q "published pieces" "$OUT/planner.log" && break; sleep 0.1; done
"$BIN/controller_node" --scenario "$SLEW" --name "mcap-st-$$" --reference stream >"$OUT/ctl.log" 2>&1 &
CTL=$!
"$BIN/plant_sim" run --scenario "$SLEW" --mode lockstep --no-spawn --name "mcap-st-$$" --out "$OUT/stream" \
	>"$OUT/plant-stream.log" 2>&1 || { kill $PLANNER $CTL 2>/dev/null; die "the streamed run failed: $(tail -3 "$OUT/plant-stream.log")"; }
wait $PLANNER || die "the planner failed: $(tail -2 "$OUT/planner.log")"
wait $CTL || die "the controller failed: $(tail -2 "$OUT/ctl.log")"
[[ -s $OUT/stream/plans.log ]] || die "the streamed run recorded no plan messages"
RUNS+=("$OUT/stream")
for run in "${RUNS[@]}"; do export_run "$run"; done

# (a) Python
python_ready=0
if [[ $(cat "$VENV/.pinned" 2>/dev/null) == "$PY_PACKAGES" ]]; then
	python_ready=1
else
	rm -rf "$VENV"
	if ! python3 -m venv "$VENV" >"$OUT/venv.log" 2>&1; then
		echo "SKIPPED: python3 -m venv failed: $(tail -1 "$OUT/venv.log")"
	elif ! "$VENV/bin/pip" install -q $PY_PACKAGES >"$OUT/pip.log" 2>&1; then
		echo "SKIPPED: pip could not install $PY_PACKAGES: $(grep -m1 -E 'ERROR' "$OUT/pip.log" || tail -1 "$OUT/pip.log")"
	else
		echo "$PY_PACKAGES" >"$VENV/.pinned"
		python_ready=1
	fi
fi
if ((python_ready)); then
	"$VENV/bin/python" -c "import mcap, mcap_ros2" || die "$PY_PACKAGES installed but do not import"
	for run in "${RUNS[@]}"; do
		"$VENV/bin/python" "$REPO/scripts/mcap/check_mcap.py" "$run/run.mcap" "$run/run.jsonl" "$run/messages.log" ||
			die "the Python reader disagrees on $run"
	done
	# the guide's figure script (docs/flight-recorder.md), on the first run: it draws from the MCAP alone
	rm -f "$OUT/figure.png"
	"$VENV/bin/python" "$REPO/scripts/mcap/plot_mcap.py" "${RUNS[0]}/run.mcap" "$OUT/figure.png" ||
		die "scripts/mcap/plot_mcap.py failed on ${RUNS[0]}/run.mcap"
	[[ -s $OUT/figure.png ]] || die "scripts/mcap/plot_mcap.py wrote no figure"
	echo "python plot_mcap.py drew $OUT/figure.png from ${RUNS[0]}/run.mcap"
fi

# (b) Node
if ! command -v node >/dev/null || ! command -v npm >/dev/null; then
	echo "SKIPPED: node and npm are not installed"
else
	node_ready=0
	if [[ $(cat "$NODE/.pinned" 2>/dev/null) == "$NODE_PACKAGES" ]]; then
		node_ready=1
	else
		rm -rf "$NODE/node_modules" "$NODE/package.json" "$NODE/package-lock.json"
		if (cd "$NODE" && npm init -y >/dev/null 2>&1 &&
			npm install --silent --no-audit --no-fund $NODE_PACKAGES >"$OUT/npm.log" 2>&1); then
			echo "$NODE_PACKAGES" >"$NODE/.pinned"
			node_ready=1
		else
			echo "SKIPPED: npm could not install $NODE_PACKAGES: $(tail -1 "$OUT/npm.log")"
		fi
	fi
	if ((node_ready)); then
		cp "$REPO/scripts/mcap/check_mcap.mjs" "$NODE/check_mcap.mjs"
		for run in "${RUNS[@]}"; do
			(cd "$NODE" && node check_mcap.mjs "$run/run.mcap" "$run/run.jsonl") || die "the Node reader disagrees on $run"
		done
	fi
fi
echo "mcap-readers: PASS"
