#!/usr/bin/env bash
# Proves the process pair on ARM64 Linux under user-mode emulation.
#
#   scripts/aarch64.sh
#
# 1. Toolchain, privately, in the cache of scripts/lib/debian.sh (shared with
#    scripts/cortex-m.sh): Debian's rustc-web with its standard library for arm64
#    (libstd-rust-web-dev:arm64, after `dpkg --add-architecture arm64`), the cross linker
#    gcc-aarch64-linux-gnu with the arm64 C library (libc6-dev-arm64-cross, only a
#    recommendation of the compiler, so named) and qemu-user-static. Nothing is
#    installed system-wide. If the packages cannot be fetched, prints one `SKIPPED: <reason>`
#    line and exits 0.
# 2. Cross-builds plant_sim and controller_node (release) for aarch64-unknown-linux-gnu.
# 3. Runs the lockstep pair under qemu-aarch64 (both processes emulated: there is no
#    binfmt_misc here, so the plant cannot spawn the emulated controller; it runs with
#    --no-spawn and the controller is started beside it) on the seed (SO(3)) and on
#    se3_circle (SE(3)), and compares each trajectory.csv with the host's `plant_sim sim`:
#    byte-identical is expected — every transcendental goes through the same Rust libm on
#    both targets, and Rust never contracts a*b+c into a fused multiply-add, so both machines
#    perform the same IEEE-754 operations in the same order. If the files differ, the
#    largest difference per column is printed and the run fails when any exceeds 1e-9
#    (absolute): a one-ulp difference somewhere (a C-library routine, say) stays near 1e-15 in
#    a contracting closed loop, while a real numerical defect shows far above 1e-9.
# 4. Runs the `eqtrack-controller` crate's unit and integration tests for the target under emulation
#    (not its doctests: rustdoc would need the private compiler's libraries as well).
#
# Environment:
#   TOOLCHAIN_CACHE=dir   toolchain cache (default <repo>/.toolchain)
#   AARCH64_PERTURB=1     multiply one host value by 1 + 1e-6 before comparing: must fail
#   AARCH64_TESTS=0       skip step 4 (the controller's test suite under emulation)
#   PLANT_SIM=path        the host's plant_sim, the reference (default: built here, with
#                         `cargo build -p plant_sim`; CI passes the tests step's, whose
#                         test-only flags change no flight)
#
# Exit: 0 on PASS or SKIPPED, 1 on any failure.
set -euo pipefail

REPO=$(cd -- "$(dirname -- "${BASH_SOURCE[0]}")/.." && pwd)
TARGET=aarch64-unknown-linux-gnu
PACKAGES=(rustc-web libstd-rust-web-dev:arm64 gcc-aarch64-linux-gnu libc6-dev-arm64-cross qemu-user-static)
TOL=1e-9

skip() {
	echo "SKIPPED: $*"
	exit 0
}
die() {
	echo "aarch64: FAIL: $*" >&2
	exit 1
}
step() { printf '[%4ds] %s\n' "$SECONDS" "$*" >&2; }

# --- 1. the private toolchain ------------------------------------------------------------

# shellcheck source=scripts/lib/debian.sh
source "$REPO/scripts/lib/debian.sh"
OUT=$CACHE/aarch64-runs
debian_architecture arm64
debian_fetch "${PACKAGES[@]}"
debian_fix_libs "$RUSTC_PRIVATE"
QEMU=$PREFIX/usr/bin/qemu-aarch64-static
LINKER=$PREFIX/usr/bin/aarch64-linux-gnu-gcc
SYSROOT=$PREFIX/usr/aarch64-linux-gnu
[[ -x $QEMU ]] || die "qemu-user-static did not provide $QEMU"
[[ -e $LINKER ]] || die "gcc-aarch64-linux-gnu did not provide $LINKER"
[[ -d $PREFIX/usr/lib/rustlib/$TARGET/lib ]] || die "libstd-rust-web-dev:arm64 did not provide $PREFIX/usr/lib/rustlib/$TARGET"
RUSTC_WRAPPED=$(debian_rustc_wrapper)
# The C library's linker scripts (libc.so) name absolute paths under /usr/aarch64-linux-gnu;
# with the prefix as the linker's sysroot they resolve inside the private copy.
mkdir -p "$CACHE/bin"
printf '#!/bin/sh\nexec %s -Wl,--sysroot=%s "$@"\n' "$LINKER" "$PREFIX" >"$CACHE/bin/aarch64-linker"
chmod +x "$CACHE/bin/aarch64-linker"
echo "toolchain: $("$RUSTC_WRAPPED" --version); $("$QEMU" --version | head -1); linker $("$LINKER" --version | head -1)"

# --- 2. cross-build ------------------------------------------------------------------------

# Its own target directory: another compiler's artefacts must not replace the host's.
CROSS_DIR=$REPO/target/aarch64-cross
# (without the release profile's debug information: nothing here reads it, and the cross
# builds are the slowest part of CI)
cross() {
	(cd "$REPO" && env -u RUSTFLAGS -u CARGO_ENCODED_RUSTFLAGS -u CARGO_BUILD_TARGET \
		RUSTC="$RUSTC_WRAPPED" CARGO_TARGET_DIR="$CROSS_DIR" CARGO_PROFILE_RELEASE_DEBUG=0 \
		PATH="$PREFIX/usr/bin:$PATH" \
		CARGO_TARGET_AARCH64_UNKNOWN_LINUX_GNU_LINKER="$CACHE/bin/aarch64-linker" \
		CARGO_TARGET_AARCH64_UNKNOWN_LINUX_GNU_RUNNER="$QEMU -L $SYSROOT" \
		"$@")
}
mkdir -p "$OUT"
step "cross-building plant_sim and controller_node for $TARGET (release)"
cross cargo build --release --locked --target "$TARGET" -p plant_sim -p controller_node \
	>"$OUT/build.log" 2>&1 || { tail -30 "$OUT/build.log" >&2; die "cross build failed (log: $OUT/build.log)"; }
BIN=$CROSS_DIR/$TARGET/release
file -b "$BIN/plant_sim" 2>/dev/null | grep -q aarch64 || [[ $(head -c 20 "$BIN/plant_sim" | od -An -tx1 -j18 -N2 | tr -d ' ') == b700 ]] ||
	die "$BIN/plant_sim is not an aarch64 executable"

# wherever cargo puts the host's build (CARGO_TARGET_DIR, or the workspace's target/)
HOST_TARGET=$(cd "$REPO" && env -u RUSTC cargo metadata --format-version 1 --no-deps |
	python3 -c 'import json, sys; print(json.load(sys.stdin)["target_directory"])')
HOST_PLANT=${PLANT_SIM:-$HOST_TARGET/debug/plant_sim}
if [[ -z ${PLANT_SIM:-} ]]; then
	step "building the host plant_sim (the reference)"
	(cd "$REPO" && env -u RUSTC cargo build --locked -p plant_sim >"$OUT/host-build.log" 2>&1) ||
		{ tail -30 "$OUT/host-build.log" >&2; die "host build failed"; }
fi
[[ -x $HOST_PLANT ]] || die "no host plant_sim at $HOST_PLANT"

# --- 3. the emulated pair against the host simulation ----------------------------------------

emu() { "$QEMU" -L "$SYSROOT" "$@"; }

compare() { # host.csv target.csv label
	python3 - "$@" "$TOL" <<'PY'
import csv, os, sys
host, target, label, tol = sys.argv[1], sys.argv[2], sys.argv[3], float(sys.argv[4])
read = lambda p: list(csv.reader(open(p)))
a, b = read(host), read(target)
perturb = os.environ.get("AARCH64_PERTURB", "0") not in ("", "0")
if perturb:
    a[len(a) // 2][1] = repr(float(a[len(a) // 2][1]) * (1 + 1e-6))
    print(f"AARCH64_PERTURB: host {a[0][1]} at row {len(a) // 2} multiplied by 1 + 1e-6")
if a == b:
    print(f"{label}: {len(b) - 1} rows x {len(b[0])} columns, byte-identical to the host")
    sys.exit(0)
if a[0] != b[0] or len(a) != len(b):
    print(f"{label}: different shape: host {len(a)} rows {a[0][:3]}..., target {len(b)} rows {b[0][:3]}...")
    sys.exit(1)
worst = []
for j, name in enumerate(a[0]):
    d = max(abs(float(x[j]) - float(y[j])) for x, y in zip(a[1:], b[1:]))
    if d > 0:
        worst.append((d, name))
worst.sort(reverse=True)
print(f"{label}: differs from the host in {len(worst)} columns; largest: "
      + ", ".join(f"{n} {d:.3e}" for d, n in worst[:5]))
sys.exit(1 if worst and worst[0][0] > tol else 0)
PY
}

pair() { # label scenario-flag scenario
	local label=$1 flag=$2 what=$3 run="aarch64-$1-$$"
	step "$label: host plant_sim sim; emulated lockstep pair"
	"$HOST_PLANT" sim "$flag" "$what" --out "$OUT/$label-host" >"$OUT/$label-host.log" 2>&1 ||
		{ cat "$OUT/$label-host.log" >&2; die "$label: host sim failed"; }
	emu "$BIN/controller_node" "$flag" "$what" --name "$run" --startup-timeout 120 \
		>"$OUT/$label-controller.log" 2>&1 &
	local ctl=$!
	if ! timeout 600 "$QEMU" -L "$SYSROOT" "$BIN/plant_sim" run "$flag" "$what" --mode lockstep \
		--no-spawn --name "$run" --out "$OUT/$label-target" >"$OUT/$label-plant.log" 2>&1; then
		kill "$ctl" 2>/dev/null || true
		tail -20 "$OUT/$label-plant.log" "$OUT/$label-controller.log" >&2
		die "$label: the emulated pair failed"
	fi
	wait "$ctl" || { tail -20 "$OUT/$label-controller.log" >&2; die "$label: the emulated controller failed"; }
	grep -h "heap allocations after start-up" "$OUT/$label-controller.log" | sed 's/^/  /' >&2 || true
	compare "$OUT/$label-host/trajectory.csv" "$OUT/$label-target/trajectory.csv" "$label" ||
		die "$label: the emulated aarch64 trajectory differs from the host's by more than $TOL"
}
pair seed --builtin seed
pair se3_circle --builtin se3_circle

# --- 4. the controller's tests on the target ---------------------------------------------------

if [[ ${AARCH64_TESTS:-1} != 0 ]]; then
	step "controller's test suite for $TARGET under qemu-aarch64"
	cross cargo test --release --locked --target "$TARGET" -p eqtrack-controller --lib --tests >"$OUT/controller-tests.log" 2>&1 ||
		{ grep -E "FAILED|panicked|error" "$OUT/controller-tests.log" | head -20 >&2; die "controller tests failed on $TARGET (log: $OUT/controller-tests.log)"; }
	passed=$(grep -Eo '^test result: ok\. [0-9]+ passed' "$OUT/controller-tests.log" | awk '{s += $4} END {print s + 0}')
	echo "controller tests on $TARGET: $passed passed"
fi

echo "aarch64: PASS (${SECONDS}s; outputs in $OUT)"
