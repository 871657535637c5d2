#!/usr/bin/env bash
# Runs the `eqtrack-controller` crate on an emulated Cortex-M4F and compares it with the host.
#
#   scripts/cortex-m.sh
#
# 1. Toolchain, privately, in the cache of scripts/lib/debian.sh (default <repo>/.toolchain,
#    git-ignored, shared with scripts/aarch64.sh): Debian's rustc-web + rust-web-src (a
#    compiler with its library sources, for `-Z build-std=core`) and qemu-system-arm, fetched
#    with `apt-get install --download-only` and unpacked with `dpkg -x`. Nothing is installed
#    system-wide. A second run re-uses the cache without apt.
#    If the packages cannot be fetched, prints one `SKIPPED: <reason>` line and exits 0.
# 2. Builds embedded/firmware-cortex-m for thumbv7em-none-eabihf with the private rustc
#    (RUSTC_BOOTSTRAP=1, linker: the rustup toolchain's rust-lld) and runs it under the
#    private qemu-system-arm (board mps2-an386) with a timeout.
# 3. Builds and runs the host program (firmware-cortex-m/host, the machine's normal cargo),
#    which prints the same lines from the same inputs (crate firmware-cases), and compares:
#      torques (TAU) and Lyapunov values at the test states (V):
#          |a_i - b_i| <= 1e-5 * max(max_j |b_j|, 1e-6)    (per line, j over its components)
#      the closed loop's Lyapunov function (L, every 0.5 s to t = 2 s, the last is the final):
#          |a - b|     <= 1e-4 * max(|b|, 1e-6)
#    a = target, b = host. Relative to the magnitude of the line (the torque vector's largest
#    entry): a component produced by cancellation carries a rounding error of a few f32 ulps of
#    the vector's magnitude, not of itself. The 1e-6 floor only matters for an exactly zero
#    line (the goal state), where it demands agreement to 1e-11.
# 4. Prints the ELF's flash/RAM footprint and the stack use the firmware measured.
# 5. Counts the instructions of one SO(3) and one SE(3) law call (error_frame world, the
#    papers' law, and reference, the default), of one controller cycle (1 and 10 reference
#    substeps), of the estimators' steps, the rejection terms, one allocation (hexarotor, ROV;
#    within reach and saturated), and one processor-in-the-loop cycle of pil_hexarotor with its
#    parts, in QEMU's translation and execution log (feature `icount`), and holds each budgeted one
#    to its limit (the SE(3) EqT at the reference and the controller's PIL cycle among them).
#
# Environment:
#   TOOLCHAIN_CACHE=dir    toolchain cache (default <repo>/.toolchain; CORTEX_M_CACHE also works)
#   CORTEX_M_TIMEOUT=s     QEMU run timeout in seconds (default 120)
#   CORTEX_M_ICOUNT_TIMEOUT=s  the same for each counting run (default 900)
#   CORTEX_M_SLOW_ALLOCATION=1  plants slow paths in the allocation (one more factorisation
#                          per iteration) and the framing (one more CRC pass per frame
#                          sent): the worst-case and framing limits must fail
#   CORTEX_M_PERTURB=1     multiply one expected (host) torque by 1.001: the comparison must fail
#   CORTEX_M_DETECTOR_COUNTS=1  print every cycle's count of the failure detector's flight
#
# Exit: 0 on PASS or SKIPPED, 1 on any failure.
set -euo pipefail

REPO=$(cd -- "$(dirname -- "${BASH_SOURCE[0]}")/.." && pwd)
FW=$REPO/embedded/firmware-cortex-m
PACKAGES=(rustc-web rust-web-src qemu-system-arm)
TARGET=thumbv7em-none-eabihf
TIMEOUT=${CORTEX_M_TIMEOUT:-120}
ICOUNT_TIMEOUT=${CORTEX_M_ICOUNT_TIMEOUT:-900}
OUT=$FW/target/cortex-m # run outputs (inside the firmware's own target dir)
ELF=$FW/target/$TARGET/release/firmware-cortex-m

skip() {
	echo "SKIPPED: $*"
	exit 0
}
die() {
	echo "cortex-m: FAIL: $*" >&2
	exit 1
}
# Progress goes to stderr: when the toolchain cannot be had, stdout is the one SKIPPED line.
step() { printf '[%4ds] %s\n' "$SECONDS" "$*" >&2; }

# --- 1. the private toolchain ------------------------------------------------------------

# shellcheck source=scripts/lib/cortex-m-toolchain.sh
source "$REPO/scripts/lib/cortex-m-toolchain.sh"

# CORTEX_M_SLOW_ALLOCATION=1 is the self-test of the worst-case and framing limits: only the
# opt-level 3 count, with the planted slow paths, which must fail (steps 2 to 4 are skipped).
if [[ ${CORTEX_M_SLOW_ALLOCATION:-} != 1 ]]; then

# --- 2. firmware: build and run under QEMU ---------------------------------------------------

mkdir -p "$OUT"
step "building the firmware ($TARGET, -Z build-std=core)"
fw_env cargo build --release --locked -Z build-std=core >"$OUT/firmware-build.log" 2>&1 ||
	{ tail -30 "$OUT/firmware-build.log" >&2; die "firmware build failed (log: $OUT/firmware-build.log)"; }

step "running the firmware under qemu-system-arm (mps2-an386, timeout ${TIMEOUT}s)"
# `cargo run` uses the runner of .cargo/config.toml (the private qemu comes first on PATH);
# the build above is up to date, so this only runs it. timeout signals the whole group.
set +e
fw_env timeout --kill-after=5 "$TIMEOUT" cargo run --release --locked -Z build-std=core \
	</dev/null >"$OUT/firmware.out" 2>"$OUT/firmware-run.log"
rc=$?
set -e
if ((rc == 124 || rc == 137)); then
	tail -5 "$OUT/firmware.out" >&2
	die "qemu timed out after ${TIMEOUT}s (output so far: $OUT/firmware.out)"
elif ((rc != 0)); then
	tail -20 "$OUT/firmware.out" "$OUT/firmware-run.log" >&2
	die "the firmware run failed: exit code $rc (1 = the firmware reported a failure or panicked)"
fi
grep -q '^END$' "$OUT/firmware.out" || die "the firmware output has no END line ($OUT/firmware.out)"
# the FPU's square root against libm's (hw_sqrt; the firmware's sqrt_check): over a million
# inputs, none differs
sqrt_line=$(grep '^SQRT ' "$OUT/firmware.out") || die "the firmware output has no SQRT line"
echo "square root (VSQRT.F32 against libm's sqrtf): $sqrt_line"
[[ $sqrt_line =~ ^SQRT\ ([0-9]+)\ inputs,\ 0\ differ$ ]] && ((BASH_REMATCH[1] >= 1000000)) ||
	die "the FPU's square root differs from libm's: $sqrt_line"

# --- 3. host: the same report on x86_64 --------------------------------------------------------

step "building and running the host program (normal cargo)"
(cd "$FW" && env -u RUSTC -u RUSTC_BOOTSTRAP -u CARGO_BUILD_TARGET CARGO_TARGET_DIR="$FW/target" \
	cargo run --release --locked -p firmware-host --target host-tuple) \
	>"$OUT/host.out" 2>"$OUT/host-build.log" ||
	{ tail -30 "$OUT/host-build.log" >&2; die "host program failed (log: $OUT/host-build.log)"; }

step "comparing"
python3 - "$OUT/firmware.out" "$OUT/host.out" <<'PY' || die "target and host differ (see the lines above)"
import math, os, struct, sys

RTOL_LAW, RTOL_LOOP, FLOOR = 1e-5, 1e-4, 1e-6

def parse(path):
    """{key: [floats]} for TAU/V/L lines, plus DONE and any ERR/PANIC lines."""
    rows, done, errors = {}, None, []
    for line in open(path, encoding="utf-8", errors="replace"):
        f = line.split()
        if not f:
            continue
        if f[0] in ("TAU", "V"):
            rows[" ".join(f[:3])] = [float(x) for x in f[3:]]
        elif f[0] == "L":
            rows[" ".join(f[:2])] = [float(x) for x in f[2:]]
        elif f[0] == "DONE":
            done = f[1]
        elif f[0] in ("ERR", "PANIC"):
            errors.append(line.rstrip())
    return rows, done, errors

def ulps(a, b):
    """Distance in f32 units in the last place."""
    def key(x):
        i = struct.unpack("<i", struct.pack("<f", x))[0]
        return i if i >= 0 else -(i & 0x7FFFFFFF)
    return abs(key(a) - key(b))

target, t_done, t_err = parse(sys.argv[1])
host, h_done, h_err = parse(sys.argv[2])
fail = []
if t_err or h_err:
    fail += [f"error line: {e}" for e in t_err + h_err]
if t_done != "1" or h_done != "1":
    fail.append(f"DONE target={t_done} host={h_done} (1 = every number finite)")
if set(target) != set(host):
    fail.append(f"different lines: only target {sorted(set(target) - set(host))}, "
                f"only host {sorted(set(host) - set(target))}")

if os.environ.get("CORTEX_M_PERTURB", "0") not in ("", "0"):
    key = "TAU so3 1"
    j = max(range(len(host[key])), key=lambda i: abs(host[key][i]))
    host[key][j] *= 1.001
    print(f"CORTEX_M_PERTURB: expected {key}[{j}] multiplied by 1.001")

print(f"{'line':<12} {'n':>2} {'max |target-host|':>18} {'tolerance':>10} {'max ulps':>8}  result")
for key in sorted(set(target) & set(host), key=lambda k: (k[0] == "L", k)):
    a, b = target[key], host[key]
    if len(a) != len(b):
        fail.append(f"{key}: {len(a)} numbers on target, {len(b)} on host")
        continue
    rtol = RTOL_LOOP if key.startswith("L ") else RTOL_LAW
    tol = rtol * max(max(abs(x) for x in b), FLOOR)
    diff = max(abs(x - y) for x, y in zip(a, b))
    ok = all(math.isfinite(x) for x in a) and diff <= tol
    print(f"{key:<12} {len(a):>2} {diff:>18.3e} {tol:>10.1e} {max(ulps(x, y) for x, y in zip(a, b)):>8}  {'ok' if ok else 'FAIL'}")
    if not ok:
        fail.append(f"{key}: target {' '.join(f'{x:.9e}' for x in a)}; "
                    f"host {' '.join(f'{x:.9e}' for x in b)}; max diff {diff:.3e} > {tol:.1e}")
final = max((k for k in target if k.startswith("L ")), key=lambda k: float(k.split()[1]), default=None)
if final in host:
    print(f"final Lyapunov ({final}): target {target[final][0]:.9e}, host {host[final][0]:.9e}")
if fail:
    print("cortex-m: comparison FAILED:")
    for f in fail:
        print("  " + f)
    sys.exit(1)
PY

# --- 4. footprint and stack ----------------------------------------------------------------

# text (code, rodata, vector table) and data initialisers are in flash; data and bss in RAM.
# llvm-size from the rustup toolchain's llvm-tools if installed, else any llvm-size, else
# binutils' size, else the ELF's own section headers.
SIZE_TOOL="" sizes=""
for t in "$HOST_SYSROOT"/lib/rustlib/*/bin/llvm-size llvm-size $(compgen -c llvm-size- | sort -uV | tail -1) size; do
	if [[ -n $t ]] && command -v "$t" >/dev/null 2>&1; then SIZE_TOOL=$t; break; fi
done
if [[ -n $SIZE_TOOL ]]; then
	sizes=$("$SIZE_TOOL" "$ELF" 2>/dev/null | awk 'NR==2 {print $1, $2, $3}') || sizes=""
fi
if [[ -z $sizes ]]; then
	# SHF_ALLOC sections: NOBITS = bss, writable = data, the rest = text (as `size` counts).
	SIZE_TOOL="ELF section headers"
	sizes=$(python3 "$REPO/scripts/lib/elf_sizes.py" "$ELF")
fi
read -r text data bss <<<"$sizes"
echo "footprint ($SIZE_TOOL): flash $((text + data)) bytes (text+rodata+vectors $text, data initialisers $data)"
echo "footprint ($SIZE_TOOL): static RAM $((data + bss)) bytes (data $data, bss $bss), plus the stack below"
while read -r _ what bytes; do
	case $what in
	so3_compute) label="Controller::compute, SO(3) EqT (one call)" ;;
	se3_compute) label="Controller::compute, SE(3) EqT (one call)" ;;
	loop_step) label="ClosedLoop::step, SO(3) seed loop (law + 10 plant + 10 reference RKMK4 substeps)" ;;
	report) label="whole report (all cases, 2 s loop, formatting, semihosting)" ;;
	*) label=$what ;;
	esac
	echo "stack (painted high-water mark): $label: $bytes bytes"
done < <(grep '^STACK ' "$OUT/firmware.out")

fi # CORTEX_M_SLOW_ALLOCATION

# --- 5. instruction counts -------------------------------------------------------------------

# The firmware built with feature `icount` runs each measured call once between two calls of
# `icount_mark`; QEMU logs each translation block's instructions when it translates it and
# every execution of a block with its symbol (chaining off, so none is skipped), so the blocks
# executed between two marks, each weighted by its instruction count, are the instructions the
# call executed. The 0 -> 1 gap (return from one mark, call of the next) is subtracted.
# At the firmware's own opt-level "s" (size), and at opt-level 3 (speed; more flash).
icount_run() { # opt-level features [label suffix]
	local label=opt-level-$1${3:+-$3} features=$2
	step "instruction counts ($label): the firmware with feature icount under qemu -d in_asm,exec,nochain"
	CARGO_PROFILE_RELEASE_OPT_LEVEL=$1 fw_env cargo build --release --locked -Z build-std=core --features "$features" \
		>"$OUT/icount-build-$label.log" 2>&1 ||
		{ tail -30 "$OUT/icount-build-$label.log" >&2; die "icount firmware build ($label) failed"; }
	cp "$ELF" "$OUT/firmware-icount-$label.elf"
	# The execution log (one line per instruction, several GB over the worst-case sets) goes
	# through a pipe to the counter, never to disk.
	local fifo=$OUT/icount-exec-$label.fifo rc counted
	rm -f "$fifo" && mkfifo "$fifo"
	count_instructions "$fifo" "$label" "$OUT/icount-$label.out" >"$OUT/icount-$label.txt" 2>&1 &
	local counter=$!
	set +e
	fw_env timeout --kill-after=5 "$ICOUNT_TIMEOUT" qemu-system-arm -cpu cortex-m4 -machine mps2-an386 -nographic \
		-semihosting-config enable=on,target=native -d in_asm,exec,nochain -D "$fifo" \
		-kernel "$OUT/firmware-icount-$label.elf" </dev/null >"$OUT/icount-$label.out" 2>"$OUT/icount-run-$label.log"
	rc=$?
	wait "$counter"
	counted=$?
	set -e
	rm -f "$fifo"
	((rc == 0)) && grep -q '^ICOUNT done true' "$OUT/icount-$label.out" ||
		{ tail -n 5 "$OUT/icount-$label.out" "$OUT/icount-run-$label.log" >&2; die "the icount firmware ($label) failed (exit $rc)"; }
	echo "instruction counts, firmware built at $label:"
	cat "$OUT/icount-$label.txt"
	((counted == 0)) || die "instruction counting failed (or a count is over its limit)"
}

count_instructions() {
python3 - "$1" "$2" "$3" <<'PY'
import os, re, sys
from collections import Counter
mark = "icount_mark"
# QEMU logs each translation block once when it translates it (in_asm: "IN: <symbol>", then one
# line per instruction) and each execution of one (exec, with nochain so none is skipped:
# "Trace 0: <host> [<cs_base>/<pc>/<flags>/<cflags>] <symbol>"). A block executed counts its
# instructions. The first 46 gaps by symbol; the worst-case sets' (thousands) as totals.
size, block, in_block = {}, None, False
gaps, totals, current, total, in_mark, runs = [], [], None, 0, False, 0
for line in open(sys.argv[1], errors="replace"):
    if line.startswith("Trace "):
        in_block = False
        pc = int(line[line.index("/") + 1:line.index("/", line.index("/") + 1)], 16)
        if mark in line:
            if not in_mark:
                if runs > 46:
                    totals.append(total)
                elif current is not None:
                    gaps.append(current)
                current, total, in_mark, runs = Counter(), 0, True, runs + 1
            continue
        in_mark = False
        n = size[pc]
        if runs > 46:
            total += n
        elif current is not None:
            current[line[line.rindex("]") + 1:].strip()] += n
    elif line.startswith("IN:"):
        in_block, block = True, None
    elif in_block and line.startswith("0x"):
        if block is None:
            block = int(line[:line.index(":")], 16)
            size[block] = 0
        size[block] += 1
if runs < 46 or len(gaps) < 45:
    sys.exit(f"expected at least 46 marks, found {runs}")
base = sum(gaps[0].values())
# gaps[i] lies between mark i and mark i + 1
names = {2: "SO(3) EqT, Controller::compute, error_frame world, f32",
         4: "SE(3) EqT (generic), Controller::compute, error_frame world, f32",
         6: "controller cycle, 1 reference substep", 8: "controller cycle, 10 reference substeps",
         10: "complementary filter step (estimator, 2 directions), f32",
         12: "pose filter step (estimator, SE(3), 1 direction + accelerometer + fix), f32",
         14: "equivariant filter step (estimator, attitude + bias, 2 directions), f32",
         16: "SO(3) EqT + momentum observer, Controller::compute_rejecting, f32",
         18: "SO(3) EqT + geometric integral, Controller::compute_rejecting, f32",
         20: "SO(3) EqT + observer + integral, Controller::compute_rejecting, f32",
         22: "SO(3) EqT + momentum observer with its clamp, Controller::compute_rejecting, f32",
         24: "allocation, hexarotor (6 rotors), within reach, f32",
         26: "allocation, ROV (8 thrusters), within reach, f32",
         28: "allocation, hexarotor, saturated, f32",
         30: "PIL framing in: pil_hexarotor's state frame with samples, deframed and decoded",
         32: "PIL cycle: Cycle::on_frame (EqF pose filter, reference step, SE(3) EqT + observer, allocation)",
         34: "PIL framing out: the command frame encoded",
         36: "PIL estimator alone: pose filter with the EqF, f32",
         38: "PIL law alone: SE(3) EqT (error_frame reference) + world-frame observer, compute_rejecting, f32",
         40: "PIL allocation alone: VehicleControl::actuate, six rotors, f32",
         42: "SO(3) EqT, Controller::compute, error_frame reference, f32",
         44: "SE(3) EqT (generic), Controller::compute, error_frame reference, f32"}
soft = re.compile(r"__aeabi_d|__adddf3|__subdf3|__muldf3|__divdf3|__fixdfsi|__floatsidf|__extendsfdf2|__truncdfsf2|compiler_builtins.*float")
for i, name in names.items():
    g = gaps[i]
    n = sum(g.values()) - base
    d = sum(c for s, c in g.items() if soft.search(s))
    top = ", ".join(f"{re.sub(r'^_ZN|17h[0-9a-f]{16}E$', '', s)[:48]} {c}" for s, c in g.most_common(4))
    print(f"ICOUNT {i // 2} {n:>6} instructions  {name}  (software double: {d}; top: {top})")
print(f"ICOUNT overhead {base} (subtracted)")
# the targets the issues set, at opt-level 3
# allocation (issue "From wrench to vehicle"): within reach a closed form, at most 5 000; a
# saturated demand runs the active-set method (17 190 measured; a ceiling against growth, the
# worst cases below are the issue "Bounded time on the microcontroller"'s)
limits = {14: 6000, 24: 5000, 26: 5000, 28: 20000} if sys.argv[2] == "opt-level-3" else {}
over = []
for i, limit in limits.items():
    n = sum(gaps[i].values()) - base
    if n > limit:
        over.append(f"ICOUNT {i // 2}: {n} instructions, over the limit of {limit} ({names[i]})")
    else:
        print(f"ICOUNT {i // 2} within its limit: {n} <= {limit}")
# the processor-in-the-loop budget (issue "The microcontroller closes the loop"): a 168 MHz
# Cortex-M4F at 1 kHz has 168 000 cycles a period. The generic SE(3) EqT at most 2 000
# instructions, held on the law at the reference (error_frame reference, the one every shipped
# scenario but the seed's flies; the papers' law, world, is printed beside it); the
# controller's whole SE(3) cycle (the EqF, the reference's step, the law with its observer, the
# allocation: Cycle::on_frame on a received frame of pil_hexarotor, which flies the law at the
# reference) at most 16 800, a tenth of the period. The serial framing around it, which only
# processor in the loop runs (a board's timer-driven loop reads its sensors instead), is
# counted and printed beside it.
count = lambda i: sum(gaps[i].values()) - base
if sys.argv[2] in ("opt-level-3", "opt-level-3-slow-allocation"):
    # the issue's framing limit (6 000, in + out), met and enforced as it is (BENCHMARKS
    # section 32); the planted slow path (one more CRC pass per frame sent) must break it
    framing = count(30) + count(34)
    print(f"framing: {framing} instructions (limit 6000)")
    if framing > 6000:
        over.append(f"framing {framing} > 6000 ({count(30)} in, {count(34)} out)")
if sys.argv[2] == "opt-level-3":
    cycle = count(32)
    print(f"ICOUNT the controller's cycle of pil_hexarotor: {cycle} instructions (estimator {count(36)}, "
          f"law {count(38)}, allocation {count(40)}, the reference's step and the glue "
          f"{cycle - count(36) - count(38) - count(40)}); with the PIL framing "
          f"({count(30)} in, {count(34)} out) {cycle + framing}")
    print(f"ICOUNT the law at the reference against the papers' (world): SE(3) {count(44)} against "
          f"{count(4)}, SO(3) {count(42)} against {count(2)}")
    for what, n, limit in [("the generic SE(3) EqT at the reference", count(44), 2000),
                           ("the controller's SE(3) cycle", cycle, 16800)]:
        if n > limit:
            sys.exit(f"ICOUNT {what}: {n} instructions, over the budget of {limit}")
        print(f"ICOUNT {what} within its budget: {n} <= {limit}")
# the worst cases (issue "Bounded time on the microcontroller";
# docs/vehicles.md, "Bounded time"): every seeded demand of each vehicle solved cold with the default budget, none stopped;
# the warm-started mean along a saturating trajectory beside it; pil_hexarotor's whole cycle on
# frames that saturate its rotors. totals[i] lies between mark 46 + i and 47 + i: the calls
# are the even ones, in the order of the firmware's WORST, WARM, SATURATED, DETECTOR,
# DETECTOR_WEAK, WEAKEN and WHEELS lines.
groups = [l.split() for l in open(sys.argv[3], errors="replace")
          if l.split()[:1] in (["WORST"], ["WARM"], ["SATURATED"], ["DETECTOR"], ["DETECTOR_WEAK"], ["WEAKEN"],
                               ["WHEELS"])]
calls = totals[0::2]
need = sum(int(g[1] if g[0] in ("SATURATED", "WHEELS") else g[2]) for g in groups)
if sys.argv[2].startswith("opt-level-3") and (len(groups) != 11 or len(calls) != need):
    sys.exit(f"the worst-case sets: {len(groups)} groups and {len(calls)} calls, expected 11 groups and {need} calls")
base_call = sum(gaps[0].values())
# The issue's limits (12 000, 12 000, 24 000; the saturated cycle 25 200): each line names its
# limit and whether it is met (docs/vehicles.md, "Bounded time"). All four are met and enforced
# as they are (BENCHMARKS sections 31, 33 and 34; the planted slow path, one more factorisation
# per iteration or per change of a dual working set, breaks them).
at, failed = 0, []
limits_wc = {"hexarotor": 12000, "rov": 12000, "spacecraft": 24000}
ceilings = {"hexarotor": 12000, "rov": 12000, "spacecraft": 24000, "cycle": 25200, "detector": 1500,
            "weaken": 2100}
met = lambda n, limit: "met" if n <= limit else "not met yet"
# "(limit N)" where the limit itself is enforced; else the limit, whether it is met, and the ceiling
limit_text = lambda n, limit, ceiling: (f"(limit {limit})" if ceiling == limit
                                        else f"(limit {limit}: {met(n, limit)}; enforced ceiling {ceiling})")
enforce = sys.argv[2].startswith("opt-level-3")
cycle_worst = None
kind_names = {1: "dead", 2: "stuck", 3: "weak"}
for g in groups:
    if g[0] == "DETECTOR":
        # the failure detector (issue "Actuator failures found, not announced"): each cycle's
        # commanded + observe on pil_rov_detect's ROV, its limit of 1 500 enforced in every
        # cycle, the naming's included (BENCHMARKS sections 35 and 38); a weak thruster's tell
        # is counted apart below
        n, found, actuator, kind, value, first = int(g[2]), int(g[3]), int(g[4]), int(g[5]), float(g[6]), int(g[7])
        counts = [c - base_call for c in calls[at:at + n]]
        at += n
        worst = max(counts)
        k = counts.index(worst)
        if os.environ.get("CORTEX_M_DETECTOR_COUNTS"):
            print("DETECTOR COUNTS", counts)
        print(f"detector: {worst} instructions per cycle {limit_text(worst, 1500, ceilings['detector'])}; "
              f"the ROV, the worst of {n} cycles, at cycle {k}")
        if actuator == 1 and first < found < n:
            # the entries that confirm the thruster prepare its change point; the next names
            # it without a test, and in that cycle the change point, the kind's fit and the
            # tell run; the shortfalls are taken out over the next cycles
            print(f"  by phase: filling its windows {counts[5]}, calibrating {max(counts[first - 10:first])}, "
                  f"testing {max(counts[first:found])} (from cycle {first}; those that confirm the thruster "
                  f"included); the cycle it names the thruster, finds the change point, fits the kind and "
                  f"tells the allocator {counts[found]}; after it "
                  f"{max(counts[found + 1:], default=0)} (the shortfalls taken out, its watch, the kind fitted "
                  f"again); mean {sum(counts) / n:.0f}")
        print(f"  thruster 1 dies at cycle 140: " + (f"found at cycle {found}, actuator {actuator}, "
              f"{kind_names.get(kind, 'no kind')} ({value:g})" if actuator < 12 else "not found"))
        if cycle_worst is not None:
            print(f"  beside the controller cycle's worst case: {cycle_worst} + {worst} = {cycle_worst + worst} "
                  f"(limit 25200: {met(cycle_worst + worst, 25200)})")
        if actuator != 1:
            failed.append(f"the detector's synthetic flight: found actuator {actuator}, not thruster 1")
        if enforce and worst > ceilings["detector"]:
            failed.append(f"detector: {worst} instructions per cycle > its ceiling {ceilings['detector']}")
        continue
    if g[0] == "DETECTOR_WEAK":
        # the same ROV's detector on a flight in which thruster 1 loses half its thrust: named
        # weak and refined, each told over the cycles after its finding, the allocator's
        # reweighting a step a cycle (BENCHMARKS section 39); every cycle within 1 500
        n, first, fa, fk, fv = int(g[2]), int(g[3]), int(g[4]), int(g[5]), float(g[6])
        last, la, lk, lv = int(g[7]), int(g[8]), int(g[9]), float(g[10])
        counts = [c - base_call for c in calls[at:at + n]]
        at += n
        worst = max(counts)
        if os.environ.get("CORTEX_M_DETECTOR_COUNTS"):
            print("DETECTOR_WEAK COUNTS", counts)
        print(f"  thruster 1 at half its thrust from cycle 140: reported {kind_names.get(fk, 'no kind')} ({fv:g}) "
              f"at cycle {first}, {kind_names.get(lk, 'no kind')} ({lv:g}) at cycle {last}; every cycle of that "
              f"flight, the tells over cycles included: worst {worst} at cycle {counts.index(worst)} "
              f"{limit_text(worst, 1500, ceilings['detector'])}; the cycles that tell, up to the reports: "
              f"{counts[first - 6:first + 1]} and {counts[last - 6:last + 1]}")
        if cycle_worst is not None:
            print(f"  beside the controller cycle's worst case: {cycle_worst} + {worst} = {cycle_worst + worst} "
                  f"(limit 25200: {met(cycle_worst + worst, 25200)})")
        if (fa, fk, la, lk) != (1, 3, 1, 3) or not first < last:
            failed.append(f"the detector's weak flight: reported actuator {fa} kind {fk}, then {la} kind {lk}, "
                          f"not thruster 1 weak, named and refined")
        if enforce and worst > ceilings["detector"]:
            failed.append(f"detector, weak flight: {worst} instructions per cycle > its ceiling {ceilings['detector']}")
        continue
    if g[0] == "WEAKEN":
        # a weak thruster told at once (issue "Actuator failures found, not announced"), as an
        # announced failure or replay's record tells it: the allocator reweighted, its thrust
        # the variable (a rank-one update of a Cholesky factor per weak thruster), a part of
        # the controller's cycle (the detector tells it over cycles instead, above); a ceiling
        # is enforced (BENCHMARKS sections 37 and 39)
        n = int(g[2])
        each = [c - base_call for c in calls[at:at + n]]
        weaken = max(each)
        at += n
        print(f"  a weak thruster told at once (announced, or replayed from a record: the allocator reweighted, "
              f"its thrust the variable; the worst of a tell, a refinement and a second weak thruster): "
              f"{weaken} instructions (enforced ceiling {ceilings['weaken']}); each: {each}")
        if enforce and weaken > ceilings["weaken"]:
            failed.append(f"a weak thruster's tell: {weaken} instructions > its ceiling {ceilings['weaken']}")
        continue
    if g[0] == "WHEELS":
        # wheels_slew's whole cycle on four reaction wheels (issue "Spacecraft on reaction
        # wheels"): within the controller cycle's budget, a tenth of a 168 MHz part's 1 kHz
        # period (wheels_slew's own period is 10 ms)
        n, saturated, closed = int(g[1]), int(g[2]), int(g[3])
        counts = [c - base_call for c in calls[at:at + n]]
        at += n
        worst = max(counts)
        print(f"wheel cycle worst case: {worst} instructions (budget 16800: {met(worst, 16800)}); over {n} "
              f"cycles of wheels_slew sweeping its wheels to their top speed ({saturated} saturated "
              f"allocations, {closed} with wheel 0's bound closed at its top speed; mean {sum(counts) / n:.0f})")
        if saturated == 0 or closed == 0:
            failed.append("the wheels' frames did not saturate their motors and close a bound")
        if enforce and worst > 16800:
            failed.append(f"wheel cycle worst case {worst} > its budget 16800")
        continue
    if g[0] == "SATURATED":
        n, saturated = int(g[1]), int(g[2])
        counts = [c - base_call for c in calls[at:at + n]]
        at += n
        worst = max(counts)
        cycle_worst = worst
        print(f"controller cycle worst case: {worst} instructions {limit_text(worst, 25200, ceilings['cycle'])}")
        print(f"  over {n} cycles of pil_hexarotor on frames that saturate its rotors ({saturated} saturated allocations; "
              f"mean {sum(counts) / n:.0f})")
        if saturated == 0:
            failed.append("the saturated PIL frames did not saturate the rotors")
        if enforce and worst > ceilings["cycle"]:
            failed.append(f"controller cycle worst case {worst} > {ceilings['cycle']}")
        continue
    name, n = g[1], int(g[2])
    counts = [c - base_call for c in calls[at:at + n]]
    at += n
    if g[0] == "WORST":
        stopped, most = int(g[3]), int(g[4])
        worst = max(counts)
        print(f"allocation worst case ({name}): {worst} instructions over {n} demands, {stopped} stopped "
              f"{limit_text(worst, limits_wc[name], ceilings[name])}")
        kinds = ["within reach", "saturated", "one failed", "two failed"]
        per = n // len(kinds)
        print("  by kind: " + ", ".join(f"{k} {max(counts[i * per:(i + 1) * per])}" for i, k in enumerate(kinds))
              + f"; most iterations {most}")
        if enforce and (worst > ceilings[name] or stopped != 0):
            failed.append(f"allocation worst case ({name}) {worst} > {ceilings[name]}, or {stopped} stopped")
    else:
        print(f"allocation warm mean ({name}): {sum(counts) / n:.0f} instructions over {n} ticks of a saturating "
              f"trajectory ({int(g[3]) / n:.2f} iterations a tick; worst {max(counts)})")
failed = over + failed
if failed:
    sys.exit("ICOUNT over a limit: " + "; ".join(failed))
# the observer's cost over the plain law (the same SO(3) case): at most 300 at opt-level 3
if sys.argv[2] == "opt-level-3":
    extra = sum(gaps[16].values()) - sum(gaps[2].values())
    if extra > 300:
        sys.exit(f"ICOUNT the observer costs {extra} instructions over the plain law, over the limit of 300")
    print(f"ICOUNT the observer's extra cost within its limit: {extra} <= 300")
PY
}

if [[ ${CORTEX_M_SLOW_ALLOCATION:-} == 1 ]]; then
	icount_run 3 worst-cases,slow-allocation slow-allocation
	echo "cortex-m: the planted slow paths passed the worst-case and framing limits"
	exit 0
fi
icount_run s icount
icount_run 3 worst-cases
# the report firmware again (opt-level "s"), so that a later `cargo run` finds it
fw_env cargo build --release --locked -Z build-std=core >"$OUT/rebuild.log" 2>&1 ||
	die "rebuilding the report firmware failed"

echo "cortex-m: PASS (${SECONDS}s; outputs in $OUT)"
