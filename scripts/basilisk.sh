#!/usr/bin/env bash
# Basilisk (AVS Lab, PyPI `bsk`) flies eqtrack's controller: examples/basilisk/spacecraft.py
# integrates a reaction-wheel scenario's spacecraft in Basilisk (its hub and its
# reactionWheelStateEffector of balanced wheels) as the plant process, in Python, speaking the
# wire through iceoryx2's own Python bindings; the unchanged controller_node flies it in
# lockstep. examples/basilisk/compare.py puts each flight beside `plant_sim sim` of the same
# scenario:
#  1. bad wheel tables (a zero spin inertia, a zero axis) are refused before Basilisk starts,
#     naming the key, and the model built from a good one is read back equal to it;
#  2. wheels_slew without friction agrees within 1e-6 rad in attitude and 1e-6 rad/s in wheel
#     speed over its 120 s;
#  3. wheel 0's spin inertia planted 0.1 % larger in Basilisk must fail that comparison;
#  4. wheels_slew with its friction (Coulomb, Stribeck, viscous) is compared and the
#     differences printed, held within 1e-5 rad and 1e-2 rad/s (how close and why:
#     docs/vehicles.md, "Reaction wheels");
#  5. the peer comparison, short: scenarios/wheels_profile.toml's spacecraft on a rest-to-rest
#     C² slew of 12 s that asks more than its wheels give, without friction, flown for 30 s by
#     Basilisk's own flight software (mrpFeedback + rwMotorTorque) inside Basilisk and by
#     eqtrack's law through the plant process, and its table (examples/basilisk/peer.py).
#     With --peer-full, instead, the three full flights docs/vehicles.md's table gives (60 s
#     each): wheels_profile as it is (with friction), without friction, and its slew in 12 s.
#
#   scripts/basilisk.sh [--figure FILE.png] [--peer-full]
#
# The venv (bsk caps matplotlib at 3.10.9, where the MuJoCo step pins 3.11.2, so it has its
# own) is made in <repo>/.toolchain/basilisk-venv (TOOLCHAIN_CACHE overrides) and removed at
# the end: it is some 600 MB. If pip cannot install bsk (or iceoryx2 beside it), prints one
# `SKIPPED: <reason>` line and exits 0; a venv that cannot be made is a failure. Exit 1 on
# failure.
set -euo pipefail
REPO=$(cd -- "$(dirname -- "${BASH_SOURCE[0]}")/.." && pwd)
CACHE=${TOOLCHAIN_CACHE:-$REPO/.toolchain}
VENV=$CACHE/basilisk-venv
OUT=$CACHE/basilisk
PACKAGES="bsk==2.12.1 iceoryx2==0.10.0"
FIGURE=$OUT/basilisk_wheels_slew.png
PEER_FULL=0
while (($#)); do
	case $1 in
	--figure) FIGURE=$2; shift 2 ;;
	--peer-full) PEER_FULL=1; shift ;;
	*) echo "usage: scripts/basilisk.sh [--figure FILE.png] [--peer-full]" >&2; exit 2 ;;
	esac
done
die() {
	echo "basilisk: FAIL: $*" >&2
	exit 1
}
mkdir -p "$CACHE" "$OUT"
[[ -f $CACHE/.gitignore ]] || printf '*\n' >"$CACHE/.gitignore"
trap 'rm -rf "$VENV"' EXIT

# shellcheck source=scripts/lib/venv.sh
source "$REPO/scripts/lib/venv.sh"
pinned_venv "$VENV" "$OUT" "$PACKAGES" strict
PY=$VENV/bin/python
"$PY" -c "import Basilisk.simulation.reactionWheelStateEffector, iceoryx2, matplotlib" ||
	die "$PACKAGES installed but do not import"

TARGET=$(cd "$REPO" && cargo metadata --format-version 1 --no-deps |
	python3 -c 'import json, sys; print(json.load(sys.stdin)["target_directory"])')
BIN=$TARGET/debug
[[ -x $BIN/plant_sim && -x $BIN/controller_node ]] ||
	(cd "$REPO" && cargo build --locked -p plant_sim -p controller_node >"$OUT/build.log" 2>&1) ||
	die "cannot build plant_sim and controller_node (log: $OUT/build.log)"
PLANT=$REPO/examples/basilisk/spacecraft.py

# fly SCENARIO DIR [--perturb]: the Basilisk plant and controller_node on SCENARIO, in lockstep,
# writing DIR/basilisk.csv
fly() {
	local scenario=$1 dir=$2 run=basilisk-$$-$RANDOM
	mkdir -p "$dir"
	"$BIN/controller_node" --scenario "$scenario" --name "$run" >"$dir/controller.log" 2>&1 &
	local ctl=$!
	if ! "$PY" "$PLANT" --name "$run" --scenario "$scenario" --out "$dir" ${3:+"$3"} >"$dir/plant.log" 2>&1; then
		kill "$ctl" 2>/dev/null || true
		die "the Basilisk plant failed: $(tail -3 "$dir/plant.log")"
	fi
	wait "$ctl" || die "controller_node failed: $(tail -3 "$dir/controller.log")"
}
# compare LABEL BASILISK TRAJECTORY ARGS...: examples/basilisk/compare.py, its lines printed
# under LABEL; dies naming LABEL when it fails
compare() {
	local label=$1 log=$2.compare.log
	shift
	if ! "$PY" "$REPO/examples/basilisk/compare.py" "$@" >"$log" 2>&1; then
		sed "s/^/  $label: /" "$log"
		die "Basilisk and plant_sim disagree ($label)"
	fi
	sed "s/^/  $label: /" "$log"
}
# sim SCENARIO DIR: plant_sim sim of SCENARIO into DIR/sim
sim() {
	"$BIN/plant_sim" sim --scenario "$1" --out "$2/sim" >"$2/sim.log" 2>&1 ||
		die "plant_sim sim failed: $(tail -3 "$2/sim.log")"
}

# 1. bad tables, refused before Basilisk starts (no Basilisk import on that path), naming the key
SLEW=$REPO/scenarios/wheels_slew.toml
for spoil in 'inertia = 2e-4|inertia = 0.0|vehicle.wheel[0].inertia' \
	'axis = [0.0, 0.8660254037844387, 0.5]|axis = [0.0, 0.0, 0.0]|vehicle.wheel[1].axis'; do
	IFS='|' read -r from to key <<<"$spoil"
	python3 - "$SLEW" "$from" "$to" >"$OUT/bad.toml" <<'PY'
import sys
text = open(sys.argv[1]).read()
print(text.replace(sys.argv[2], sys.argv[3], 1), end="")
PY
	code=0
	"$PY" "$PLANT" --scenario "$OUT/bad.toml" --check-only >"$OUT/bad.log" 2>&1 || code=$?
	[[ $code == 2 ]] && grep -qF "$key" "$OUT/bad.log" ||
		die "a bad table ($key) was not refused with exit 2 naming it: exit $code, $(cat "$OUT/bad.log")"
	echo "  refused before Basilisk starts: $(head -1 "$OUT/bad.log")"
done
"$PY" "$PLANT" --scenario "$SLEW" --check-only | sed 's/^/  /' || die "the model of wheels_slew is not the scenario's"

# 2. without friction: within 1e-6 rad and 1e-6 rad/s
FREE=$OUT/wheels_slew_frictionless.toml
grep -v -E '^(friction_|stribeck_speed)' "$SLEW" >"$FREE"
fly "$FREE" "$OUT/free"
sed 's/^/  /' "$OUT/free/plant.log"
grep -h "heap allocations after" "$OUT/free/controller.log" | sed 's/^/  /' || true
sim "$FREE" "$OUT/free"
compare "without friction" "$OUT/free/basilisk.csv" "$OUT/free/sim/trajectory.csv" \
	--attitude 1e-6 --speed 1e-6 --figure "$FIGURE" \
	--title "wheels_slew without friction: Basilisk as the plant process, the unchanged controller_node"

# 3. the comparison can fail: wheel 0's Js 0.1 % larger in Basilisk must be caught
fly "$FREE" "$OUT/perturbed" --perturb
if "$PY" "$REPO/examples/basilisk/compare.py" "$OUT/perturbed/basilisk.csv" "$OUT/free/sim/trajectory.csv" \
	--attitude 1e-6 --speed 1e-6 >"$OUT/perturbed/compare.log" 2>&1; then
	die "a 0.1 % larger spin inertia passed the comparison: it cannot fail"
fi
grep -q "FAIL: a difference above" "$OUT/perturbed/compare.log" ||
	die "the planted error's comparison failed for another reason: $(tail -3 "$OUT/perturbed/compare.log")"
echo "  planted error caught: $(grep -m1 largest "$OUT/perturbed/compare.log")"

# 4. with friction: compared, and how close printed
fly "$SLEW" "$OUT/friction"
sim "$SLEW" "$OUT/friction"
compare "with friction" "$OUT/friction/basilisk.csv" "$OUT/friction/sim/trajectory.csv" --attitude 1e-5 --speed 1e-2

# 5. the peer law: Basilisk's mrpFeedback + rwMotorTorque inside Basilisk, eqtrack's law
# through the plant process, on the same slew
# variant DIR SLEW_SECONDS DURATION FRICTION(0|1): wheels_profile.toml and its waypoints in DIR,
# the slew's end at SLEW_SECONDS, flown for DURATION s, with or without its friction
variant() {
	local dir=$1
	mkdir -p "$dir" || die "cannot make $dir"
	if (($4)); then
		cp "$REPO/scenarios/wheels_profile.toml" "$dir/" || die "cannot copy wheels_profile.toml"
	else
		grep -v -E '^(friction_|stribeck_speed)' "$REPO/scenarios/wheels_profile.toml" >"$dir/wheels_profile.toml" ||
			die "cannot write $dir/wheels_profile.toml"
	fi
	sed -i "s/^duration = .*/duration = $3/" "$dir/wheels_profile.toml" || die "cannot set the duration"
	grep -q "^duration = $3\$" "$dir/wheels_profile.toml" || die "the variant's duration is not $3"
	sed "s/^30.0,/$2,/" "$REPO/scenarios/wheels_profile.csv" >"$dir/wheels_profile.csv" || die "cannot write the waypoints"
	grep -q "^$2," "$dir/wheels_profile.csv" || die "the variant's waypoints: $(cat "$dir/wheels_profile.csv")"
}
# peer DIR TITLE: both flights of DIR/wheels_profile.toml and their table
peer() {
	fly "$1/wheels_profile.toml" "$1/eqtrack"
	"$PY" "$REPO/examples/basilisk/peer.py" --scenario "$1/wheels_profile.toml" --eqtrack "$1/eqtrack/basilisk.csv" \
		--out "$1" --figure "$1/peer.png" --title "$2" >"$1/peer.log" 2>&1 ||
		die "the peer comparison failed: $(tail -3 "$1/peer.log")"
	echo "  peer comparison, $2:"
	{ grep '^|' "$1/peer.log" || true; } | sed 's/^/    /'
	{ grep '^|' "$1/peer.log" || true; } | python3 -c '
import sys
rows = [l.split("|")[1:-1] for l in sys.stdin]
sys.exit(0 if len(rows) == 8 and all(len(r) == 3 and all(c.strip() for c in r) for r in rows) else 1)' ||
		die "the peer table is not complete: $(cat "$1/peer.log")"
}
if ((PEER_FULL)); then
	variant "$OUT/peer-friction" 30.0 60.0 1
	peer "$OUT/peer-friction" "wheels_profile (a 30 s slew, with friction)"
	variant "$OUT/peer-free" 30.0 60.0 0
	peer "$OUT/peer-free" "wheels_profile without friction"
	variant "$OUT/peer-fast" 12.0 60.0 0
	peer "$OUT/peer-fast" "wheels_profile's slew in 12 s, without friction"
else
	variant "$OUT/peer-short" 12.0 30.0 0
	peer "$OUT/peer-short" "a 12 s slew, 30 s flown, without friction"
fi

echo "basilisk: PASS"
