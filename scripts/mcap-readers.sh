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
# The run is the observer's set-point (`scenarios/reject_so3.toml`, 4 s in lockstep), so
# every channel, the disturbance terms included, is there.
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
[[ -x $BIN/plant_sim && -x $BIN/controller_node && -x $BIN/eqtrack-export ]] ||
	(cd "$REPO" && cargo build --locked -p plant_sim -p controller_node -p export >"$OUT/build.log" 2>&1) ||
	die "cannot build plant_sim, controller_node and eqtrack-export (log: $OUT/build.log)"

rm -rf "$OUT/run"
"$BIN/plant_sim" run --scenario "$REPO/scenarios/reject_so3.toml" --mode lockstep --duration 4 \
	--name "mcap-$$" --out "$OUT/run" >"$OUT/plant.log" 2>&1 || die "the run failed: $(tail -3 "$OUT/plant.log")"
"$BIN/plant_sim" export "$OUT/run" || die "export to MCAP failed"
"$BIN/plant_sim" export "$OUT/run" --format jsonl >/dev/null || die "export to JSONL failed"
MCAP=$OUT/run/run.mcap
JSONL=$OUT/run/run.jsonl

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
	"$VENV/bin/python" "$REPO/scripts/mcap/check_mcap.py" "$MCAP" "$JSONL" || die "the Python reader disagrees"
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
		(cd "$NODE" && node check_mcap.mjs "$MCAP" "$JSONL") || die "the Node reader disagrees"
	fi
fi
echo "mcap-readers: PASS"
