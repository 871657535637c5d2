#!/usr/bin/env bash
# The Python path, tested as a new user would take it: a venv with iceoryx2's own Python
# bindings (pip install iceoryx2==0.10.0), and two copies of examples/python/observe.py
# attached at once to a short real-time run of the pair. Each must read at least 10 distinct,
# increasing sequence numbers.
#
#   scripts/python-observer.sh
#
# The venv is cached in <repo>/.toolchain/pyvenv (TOOLCHAIN_CACHE overrides). If the package
# cannot be installed, prints one `SKIPPED: <reason>` line and exits 0. Exit 1 on failure.
set -euo pipefail
REPO=$(cd -- "$(dirname -- "${BASH_SOURCE[0]}")/.." && pwd)
CACHE=${TOOLCHAIN_CACHE:-$REPO/.toolchain}
VENV=$CACHE/pyvenv
OUT=$CACHE/python-observer
die() {
	echo "python-observer: FAIL: $*" >&2
	exit 1
}
mkdir -p "$CACHE" "$OUT"
[[ -f $CACHE/.gitignore ]] || printf '*\n' >"$CACHE/.gitignore"

if ! "$VENV/bin/python" -c "import iceoryx2" 2>/dev/null; then
	rm -rf "$VENV"
	python3 -m venv "$VENV" >"$OUT/venv.log" 2>&1 || { echo "SKIPPED: python3 -m venv failed: $(tail -1 "$OUT/venv.log")"; exit 0; }
	"$VENV/bin/pip" install -q iceoryx2==0.10.0 >"$OUT/pip.log" 2>&1 ||
		{ echo "SKIPPED: pip could not install iceoryx2==0.10.0: $(grep -m1 -E 'ERROR' "$OUT/pip.log" || tail -1 "$OUT/pip.log")"; exit 0; }
fi

TARGET=$(cd "$REPO" && cargo metadata --format-version 1 --no-deps |
	python3 -c 'import json, sys; print(json.load(sys.stdin)["target_directory"])')
PLANT=$TARGET/debug/plant_sim
[[ -x $PLANT && -x $TARGET/debug/controller_node ]] ||
	(cd "$REPO" && cargo build --locked -p plant_sim -p controller_node >"$OUT/build.log" 2>&1) ||
	die "cannot build plant_sim and controller_node (log: $OUT/build.log)"

run=pyobs-$$
# a vehicle: the commands carry actuator commands, which the observers print
"$PLANT" run --scenario "$REPO/scenarios/hexarotor_eqf.toml" --duration 4 --name "$run" \
	--out "$OUT/run" >"$OUT/plant.log" 2>&1 &
plant=$!
for i in 1 2; do
	"$VENV/bin/python" "$REPO/examples/python/observe.py" --name "$run" --count 30 --timeout 30 \
		>"$OUT/observer-$i.out" 2>&1 &
	eval "obs$i=\$!"
done
ok=1
# shellcheck disable=SC2154
wait "$obs1" || ok=0
# shellcheck disable=SC2154
wait "$obs2" || ok=0
wait "$plant" || die "the pair failed: $(tail -3 "$OUT/plant.log")"
((ok)) || die "an observer failed: $(tail -3 "$OUT"/observer-*.out)"
for i in 1 2; do
	python3 - "$OUT/observer-$i.out" "$i" <<'PY' || die "observer $i: see $OUT/observer-$i.out"
import sys
lines = [l for l in open(sys.argv[1]) if l.startswith("seq ")]
seqs = [int(l.split()[1]) for l in lines]
# every answered state shows the vehicle's six rotor commands
rotors = all(len(l.split("  u ")[1].split()) == 6 for l in lines if "  L nan" not in l)
ok = len(seqs) >= 10 and len(set(seqs)) == len(seqs) and seqs == sorted(seqs) and rotors
print(f"observer {sys.argv[2]}: {len(seqs)} states, seq {seqs[0] if seqs else '-'} .. {seqs[-1] if seqs else '-'}, "
      f"{'distinct and increasing, rotor commands shown' if ok else 'NOT distinct and increasing with rotor commands (or fewer than 10)'}")
sys.exit(0 if ok else 1)
PY
done
grep -hE "^deadline misses|heap allocations after" "$OUT/plant.log" | sed 's/^/  /' || true
echo "python-observer: PASS"
