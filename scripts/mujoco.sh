#!/usr/bin/env bash
# An independent physics engine flies the hexarotor: MuJoCo (PyPI `mujoco`) integrates
# examples/mujoco/hexarotor.xml as the plant process, in Python, speaking the wire through
# iceoryx2's own Python bindings; the unchanged controller_node flies it in lockstep.
# examples/mujoco/compare.py then puts the flight beside `plant_sim sim` of the same scenario
# and requires the position and attitude to agree within 1e-6 over the whole run. Then the
# same figure-eight moved (1000, -700, 300) m away (`plant_sim move`) flies in MuJoCo as in
# `plant_sim sim` of the moved scenario, within the same 1e-6.
#
#   scripts/mujoco.sh [--figure FILE.png]
#
# The venv is cached in <repo>/.toolchain/mujoco-venv (TOOLCHAIN_CACHE overrides). If the
# packages cannot be installed, prints one `SKIPPED: <reason>` line and exits 0. Exit 1 on
# failure.
set -euo pipefail
REPO=$(cd -- "$(dirname -- "${BASH_SOURCE[0]}")/.." && pwd)
CACHE=${TOOLCHAIN_CACHE:-$REPO/.toolchain}
VENV=$CACHE/mujoco-venv
OUT=$CACHE/mujoco
PACKAGES="mujoco==4.0.0 iceoryx2==0.10.0 matplotlib==3.11.2"
FIGURE=$OUT/mujoco_hexarotor.png
[[ ${1:-} == --figure && -n ${2:-} ]] && FIGURE=$2
die() {
	echo "mujoco: FAIL: $*" >&2
	exit 1
}
mkdir -p "$CACHE" "$OUT"
[[ -f $CACHE/.gitignore ]] || printf '*\n' >"$CACHE/.gitignore"

# shellcheck source=scripts/lib/venv.sh
source "$REPO/scripts/lib/venv.sh"
pinned_venv "$VENV" "$OUT" "$PACKAGES"
"$VENV/bin/python" -c "import mujoco, iceoryx2, matplotlib" || die "$PACKAGES installed but do not import"

TARGET=$(cd "$REPO" && cargo metadata --format-version 1 --no-deps |
	python3 -c 'import json, sys; print(json.load(sys.stdin)["target_directory"])')
BIN=$TARGET/debug
[[ -x $BIN/plant_sim && -x $BIN/controller_node ]] ||
	(cd "$REPO" && cargo build --locked -p plant_sim -p controller_node >"$OUT/build.log" 2>&1) ||
	die "cannot build plant_sim and controller_node (log: $OUT/build.log)"

SCENARIO=$REPO/scenarios/hexarotor_eight.toml
# fly DIR [--perturb]: the MuJoCo plant and controller_node on $SCENARIO, in lockstep, writing
# DIR/mujoco.csv
fly() {
	local dir=$1 run=mujoco-$$-${2:-plain}-$RANDOM
	mkdir -p "$dir"
	"$BIN/controller_node" --scenario "$SCENARIO" --name "$run" >"$dir/controller.log" 2>&1 &
	local ctl=$!
	if ! "$VENV/bin/python" "$REPO/examples/mujoco/hexarotor.py" --name "$run" --scenario "$SCENARIO" \
		--out "$dir" ${2:+--perturb} >"$dir/plant.log" 2>&1; then
		kill "$ctl" 2>/dev/null || true
		die "the MuJoCo plant failed: $(tail -3 "$dir/plant.log")"
	fi
	wait "$ctl" || die "controller_node failed: $(tail -3 "$dir/controller.log")"
}
fly "$OUT"
sed 's/^/  /' "$OUT/plant.log"
grep -h "heap allocations after" "$OUT/controller.log" | sed 's/^/  /' || true
"$BIN/plant_sim" sim --scenario "$SCENARIO" --out "$OUT/sim" >"$OUT/sim.log" 2>&1 || die "plant_sim sim failed: $(tail -3 "$OUT/sim.log")"
"$VENV/bin/python" "$REPO/examples/mujoco/compare.py" "$OUT/mujoco.csv" "$OUT/sim/trajectory.csv" \
	--figure "$FIGURE" --tol 1e-6 || die "MuJoCo and plant_sim disagree"
# the comparison can fail: rotor 0 pushing 0.1 % harder in MuJoCo must be caught
fly "$OUT/perturbed" perturb
if "$VENV/bin/python" "$REPO/examples/mujoco/compare.py" "$OUT/perturbed/mujoco.csv" \
	"$OUT/sim/trajectory.csv" --tol 1e-6 >"$OUT/perturbed/compare.log"; then
	die "a 0.1 % stronger rotor passed the comparison: it cannot fail"
fi
echo "  planted error caught: $(grep -m1 largest "$OUT/perturbed/compare.log")"
# the figure-eight a kilometre and more from the origin
"$BIN/plant_sim" move --scenario "$SCENARIO" --offset 1000,-700,300 --out "$OUT/far" >"$OUT/move.log" 2>&1 ||
	die "plant_sim move failed: $(tail -3 "$OUT/move.log")"
SCENARIO=$OUT/far/hexarotor_eight.toml
fly "$OUT/far"
"$BIN/plant_sim" sim --scenario "$SCENARIO" --out "$OUT/far/sim" >"$OUT/far/sim.log" 2>&1 ||
	die "plant_sim sim of the moved scenario failed: $(tail -3 "$OUT/far/sim.log")"
"$VENV/bin/python" "$REPO/examples/mujoco/compare.py" "$OUT/far/mujoco.csv" "$OUT/far/sim/trajectory.csv" \
	--tol 1e-6 | sed 's/^/  far away: /' || die "MuJoCo and plant_sim disagree on the figure-eight moved far away"
echo "mujoco: PASS"
