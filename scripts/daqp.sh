#!/usr/bin/env bash
# DAQP (Arnström, Bemporad and Axehill, IEEE TAC 2022; the `daqp` Python package, in a private
# venv) beside eqtrack's allocation (docs/vehicles.md, "Bounded time"):
#
#   scripts/daqp.sh
#
# 1. An independent re-solve: every vehicle scenario flown by `plant_sim sim`, and every row of
#    its trajectory.csv re-solved by DAQP from demand_i and the scenario's own actuator table
#    (scripts/daqp/resolve.py): u_cmd within 1e-6 of the largest bound, and the last stage's
#    optimality conditions met to 1e-6. A planted 1e-3 change of one command must fail.
# 2. The peer benchmark: the allocation crate's example `peer` times eqtrack on
#    saturated hexarotor and ROV problems (cold, and warm along a saturating trajectory), and
#    DAQP solves the same problems (scripts/daqp/bench.py): the torque stage alone and the full
#    hierarchy, DAQP's own solve_time beside eqtrack's median, in the same run.
#
# Prints SKIPPED: when pip cannot install the packages. Exit 0 on PASS or SKIPPED, 1 on a failure.
set -euo pipefail
REPO=$(cd -- "$(dirname -- "${BASH_SOURCE[0]}")/.." && pwd)
CACHE=${TOOLCHAIN_CACHE:-$REPO/.toolchain}
VENV=$CACHE/daqp-venv
OUT=$CACHE/daqp
PACKAGES="daqp==0.11.0 numpy==2.4.6"
die() {
	echo "daqp: FAIL: $*" >&2
	exit 1
}
mkdir -p "$CACHE" "$OUT"
[[ -f $CACHE/.gitignore ]] || printf '*\n' >"$CACHE/.gitignore"

# shellcheck source=scripts/lib/venv.sh
source "$REPO/scripts/lib/venv.sh"
pinned_venv "$VENV" "$OUT" "$PACKAGES"
"$VENV/bin/python" -c "import daqp, numpy" || die "$PACKAGES installed but do not import"

TARGET=$(cd "$REPO" && cargo metadata --format-version 1 --no-deps |
	python3 -c 'import json, sys; print(json.load(sys.stdin)["target_directory"])')
PLANT=$TARGET/debug/plant_sim
[[ -x $PLANT ]] || (cd "$REPO" && cargo build --locked -p plant_sim >"$OUT/build.log" 2>&1) ||
	die "cannot build plant_sim (log: $OUT/build.log)"

# 1. every row of every vehicle scenario, re-solved
for s in hexarotor_eight hexarotor_eqf pil_hexarotor rov_failure spacecraft se2_vessel; do
	"$PLANT" sim --scenario "$REPO/scenarios/$s.toml" --out "$OUT/$s" >"$OUT/$s.log" 2>&1 ||
		die "plant_sim sim $s failed: $(tail -3 "$OUT/$s.log")"
	"$VENV/bin/python" "$REPO/scripts/daqp/resolve.py" "$REPO/scenarios/$s.toml" "$OUT/$s/trajectory.csv" ||
		die "$s: eqtrack's allocation differs from DAQP's"
done
if "$VENV/bin/python" "$REPO/scripts/daqp/resolve.py" "$REPO/scenarios/spacecraft.toml" \
	"$OUT/spacecraft/trajectory.csv" --perturb >"$OUT/perturbed.log" 2>&1; then
	die "a command moved by 1e-3 of the largest bound passed the comparison: $(cat "$OUT/perturbed.log")"
fi
echo "daqp: a command moved by 1e-3 of the largest bound is caught: $(tail -1 "$OUT/perturbed.log")"

# 2. the peer benchmark
# the workspace's dev profile (opt-level 2): `cargo test --workspace` has built the example
# already, with the workspace's features (`-p eqtrack-allocation` would resolve them anew and rebuild)
(cd "$REPO" && cargo build --locked -q --workspace --example peer) >"$OUT/peer-build.log" 2>&1 ||
	die "cannot build the peer example (log: $OUT/peer-build.log)"
(cd "$REPO" && "$TARGET/debug/examples/peer" "$OUT") >"$OUT/eqtrack.jsonl" 2>"$OUT/peer.log" ||
	die "the peer example failed: $(tail -3 "$OUT/peer.log")"
"$VENV/bin/python" "$REPO/scripts/daqp/bench.py" "$OUT/problems.csv" "$OUT/eqtrack.jsonl" |
	tee "$OUT/bench.txt" || die "DAQP and eqtrack answer the benchmark's problems differently"
echo "daqp: PASS"
