#!/usr/bin/env bash
# Processor in the loop (docs/pil.md): the controller on the emulated Cortex-M4F (QEMU's
# mps2-an386, the RTIC firmware of embedded/pil-firmware), the plant on the host, one state
# and one command a period over the UART (on a TCP socket), and the run compared with the
# in-process f32 simulation.
#
#   scripts/pil.sh [--scenario FILE] [--out DIR]
#
# For each scenario (default: the seed on SO(3), se3_circle on SE(3), reject_so3 with the
# disturbance observer):
#  1. plant_sim pil-config writes the scenario's firmware configuration; the firmware is
#     built with it (private toolchain of scripts/lib/cortex-m-toolchain.sh);
#  2. QEMU starts with UART0 on a TCP socket (nodelay) and waits for the plant;
#  3. plant_sim run --mode lockstep --transport tcp:127.0.0.1:PORT writes the usual outputs;
#  4. plant_sim sim --controller-scalar f32 writes the reference;
#  5. the two trajectory.csv must be equal byte for byte: `PIL: PASS`, or the first row and
#     column that differ.
# Then, on the seed at a 20 ms period in real time: a scenario mismatch is refused on both
# sides, a frame corrupted on the line is counted and held over, a firmware reset through
# QEMU's monitor (system_reset) enters safe mode and the handshake brings it back. Last, the
# firmware's flash, static RAM and stack high-water mark.
#
# Environment: TOOLCHAIN_CACHE (as scripts/cortex-m.sh), PLANT_SIM (default: the workspace's
# target/debug/plant_sim, built with the test-only flags if missing).
# Prints `SKIPPED: <reason>` and exits 0 only when Debian's packages cannot be fetched.
set -euo pipefail

REPO=$(cd -- "$(dirname -- "${BASH_SOURCE[0]}")/.." && pwd)
FW=$REPO/embedded/pil-firmware
PACKAGES=(rustc-web rust-web-src qemu-system-arm)
TARGET=thumbv7em-none-eabihf
ELF=$FW/target/$TARGET/release/pil-firmware
SCENARIOS=()
OUT=$FW/target/pil
while (($#)); do
	case $1 in
	--scenario) SCENARIOS+=("$(realpath "$2")"); shift 2 ;;
	--out) OUT=$(realpath -m "$2"); shift 2 ;;
	*) echo "usage: scripts/pil.sh [--scenario FILE]... [--out DIR]" >&2; exit 2 ;;
	esac
done
((${#SCENARIOS[@]})) || SCENARIOS=("$REPO/scenarios/seed.toml" "$REPO/scenarios/se3_circle.toml" "$REPO/scenarios/reject_so3.toml")

skip() {
	echo "SKIPPED: $*"
	exit 0
}
die() {
	echo "PIL: FAIL: $*" >&2
	exit 1
}
step() { printf '[%4ds] %s\n' "$SECONDS" "$*" >&2; }

# shellcheck source=scripts/lib/cortex-m-toolchain.sh
source "$REPO/scripts/lib/cortex-m-toolchain.sh"

mkdir -p "$OUT"
TARGET_DIR=$(cd "$REPO" && cargo metadata --format-version 1 --no-deps |
	python3 -c 'import json, sys; print(json.load(sys.stdin)["target_directory"])')
PLANT=${PLANT_SIM:-$TARGET_DIR/debug/plant_sim}
if [[ ! -x $PLANT ]]; then
	step "building plant_sim (with the test-only flags)"
	(cd "$REPO" && cargo build --locked -p plant_sim --features fault-injection >"$OUT/plant-build.log" 2>&1) ||
		die "cannot build plant_sim (log: $OUT/plant-build.log)"
fi

QEMU_PID=""
stop_qemu() {
	[[ -n $QEMU_PID ]] && kill "$QEMU_PID" 2>/dev/null && wait "$QEMU_PID" 2>/dev/null
	QEMU_PID=""
	return 0
}
trap stop_qemu EXIT

free_port() { python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])'; }

# build FILE TAG: the firmware for scenario FILE, copied to OUT/TAG.elf
build() {
	local file=$1 tag=$2
	"$PLANT" pil-config --scenario "$file" --out "$OUT/$tag.config" >"$OUT/$tag.config.log" 2>&1 ||
		die "$tag: plant_sim pil-config failed: $(tail -2 "$OUT/$tag.config.log")"
	PIL_CONFIG="$OUT/$tag.config" fw_env cargo build --release --locked -Z build-std=core \
		>"$OUT/$tag.build.log" 2>&1 ||
		{ tail -30 "$OUT/$tag.build.log" >&2; die "$tag: the firmware build failed (log: $OUT/$tag.build.log)"; }
	cp "$ELF" "$OUT/$tag.elf"
}

# start TAG: QEMU with the firmware OUT/TAG.elf, its UART on PORT (set), its monitor on a
# Unix socket OUT/TAG.monitor; returns once QEMU waits for the plant.
start() {
	local tag=$1
	PORT=$(free_port)
	rm -f "$OUT/$tag.monitor"
	LD_LIBRARY_PATH=$LIBS "$QEMU" -machine mps2-an386 -cpu cortex-m4 -display none \
		-semihosting-config enable=on,target=native \
		-serial "tcp:127.0.0.1:$PORT,server=on,wait=on,nodelay=on" \
		-monitor "unix:$OUT/$tag.monitor,server=on,wait=off" \
		-kernel "$OUT/$tag.elf" >"$OUT/$tag.qemu.out" 2>"$OUT/$tag.qemu.err" &
	QEMU_PID=$!
	for _ in $(seq 200); do
		grep -q "waiting for connection" "$OUT/$tag.qemu.err" 2>/dev/null && return 0
		kill -0 "$QEMU_PID" 2>/dev/null || die "$tag: qemu exited: $(cat "$OUT/$tag.qemu.err")"
		sleep 0.05
	done
	die "$tag: qemu did not open its UART socket (stderr: $OUT/$tag.qemu.err)"
}

# compare A B: the first row and column that differ, or nothing
compare() {
	python3 - "$1" "$2" <<'PY'
import csv, sys
a = list(csv.reader(open(sys.argv[1])))
b = list(csv.reader(open(sys.argv[2])))
if a[0] != b[0]:
    sys.exit(f"the columns differ: {a[0]} vs {b[0]}")
for i, (ra, rb) in enumerate(zip(a[1:], b[1:]), start=1):
    for j, (x, y) in enumerate(zip(ra, rb)):
        if x != y:
            sys.exit(f"row {i} (t = {ra[0]}), column {a[0][j]}: PIL {x}, f32 simulation {y}")
if len(a) != len(b):
    sys.exit(f"{len(a) - 1} rows against {len(b) - 1}")
PY
}

fails=0
for file in "${SCENARIOS[@]}"; do
	tag=$(basename "$file" .toml)
	step "$tag: building the firmware with its configuration"
	build "$file" "$tag"
	start "$tag"
	step "$tag: plant_sim run --mode lockstep --transport tcp:127.0.0.1:$PORT"
	"$PLANT" run --mode lockstep --scenario "$file" --transport "tcp:127.0.0.1:$PORT" --no-record \
		--lockstep-timeout 30 --out "$OUT/$tag-pil" >"$OUT/$tag-pil.log" 2>&1 ||
		{ tail -5 "$OUT/$tag-pil.log" "$OUT/$tag.qemu.out" >&2; die "$tag: the PIL run failed (log: $OUT/$tag-pil.log)"; }
	sleep 0.2
	stop_qemu
	"$PLANT" sim --scenario "$file" --controller-scalar f32 --out "$OUT/$tag-f32" >"$OUT/$tag-f32.log" 2>&1 ||
		die "$tag: plant_sim sim --controller-scalar f32 failed (log: $OUT/$tag-f32.log)"
	grep -h "serial link" "$OUT/$tag-pil.log" || true
	grep -h "^STACK\|^PIL BYE" "$OUT/$tag.qemu.out" || true
	if why=$(compare "$OUT/$tag-pil/trajectory.csv" "$OUT/$tag-f32/trajectory.csv" 2>&1); then
		echo "PIL: PASS $tag ($(($(wc -l <"$OUT/$tag-pil/trajectory.csv") - 1)) rows equal, byte for byte)"
	else
		echo "PIL: FAIL $tag: $why"
		fails=$((fails + 1))
	fi
done
((fails == 0)) || die "$fails scenario(s) differ"
echo "PIL: PASS"
