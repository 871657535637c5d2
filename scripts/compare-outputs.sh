#!/usr/bin/env bash
# Byte-for-byte comparison of what two builds write: a refactoring must change no output byte.
#
#   bash scripts/compare-outputs.sh [--world] BASE_BIN_DIR NEW_BIN_DIR
#
# --world: the new build flies every scenario with `[controller] error_frame = "world"` (the
# papers' law as written), the base each scenario as it is: for a base from before the key
# existed, the new build must then write exactly what the base wrote.
#
# Each directory holds a plant_sim and a controller_node (e.g. two target/debug directories,
# one of them built from a `git worktree` of the base commit). Compared with cmp, file by
# file:
#   * `plant_sim sim` of every scenario in scenarios/: every file it writes (trajectory.csv,
#     summary.json, the figures);
#   * lockstep pair runs of seed and se3_circle: trajectory.csv and messages.log (a lockstep
#     log holds no clock reading and no process id; a log of another format version, written
#     after a wire protocol change, is reported and not compared);
#   * `plant_sim reference` of every waypoint scenario: every file it writes;
#   * the studies, small: `montecarlo` (the laws, and the estimators), `noise`, `rejection`
#     (with its Monte Carlo); every file each writes;
#   * `plant_sim replay` of the lockstep seed run, bit for bit and as a what-if (another law):
#     what it prints and every file the what-if writes.
# Prints one line per comparison and `compare-outputs: PASS`, or the first file that differs
# and exit status 1.
set -euo pipefail
REPO=$(cd -- "$(dirname -- "${BASH_SOURCE[0]}")/.." && pwd)
WORLD=0
[[ ${1:-} == --world ]] && { WORLD=1; shift; }
[[ $# -eq 2 ]] || { echo "usage: $0 [--world] BASE_BIN_DIR NEW_BIN_DIR" >&2; exit 2; }
BASE=$(cd "$1" && pwd)
NEW=$(cd "$2" && pwd)
OUT=$(mktemp -d)
trap 'rm -rf "$OUT"' EXIT
die() { echo "compare-outputs: FAIL: $*" >&2; exit 1; }

# the scenarios the new build flies: scenarios/ itself, or with --world a copy (waypoint files
# beside it) whose every [controller] table says error_frame = "world"
NEW_SCENARIOS=$REPO/scenarios
if [[ $WORLD -eq 1 ]]; then
	NEW_SCENARIOS=$OUT/world-scenarios
	cp -r "$REPO/scenarios" "$NEW_SCENARIOS"
	for f in "$NEW_SCENARIOS"/*.toml; do
		grep -q '^error_frame *=' "$f" && sed -i 's/^error_frame *=.*/error_frame = "world"/' "$f" ||
			sed -i 's/^\[controller\]$/[controller]\nerror_frame = "world"/' "$f"
		grep -q '^error_frame = "world"$' "$f" || die "--world: cannot set error_frame in $f"
	done
	echo "compare-outputs: the new build flies every scenario with error_frame = \"world\""
fi
# the scenarios the base flies: with --world, as a base from before the key reads them (no
# error_frame line)
BASE_SCENARIOS=$REPO/scenarios
if [[ $WORLD -eq 1 ]]; then
	BASE_SCENARIOS=$OUT/base-scenarios
	cp -r "$REPO/scenarios" "$BASE_SCENARIOS"
	sed -i '/^error_frame *=/d' "$BASE_SCENARIOS"/*.toml
fi
# the new build's arguments: scenario files from NEW_SCENARIOS, built-ins as their files there
new_args() {
	local prev=""
	for a in "$@"; do
		if [[ $WORLD -eq 1 && $prev == --builtin ]]; then
			printf '%s\n' "$NEW_SCENARIOS/$a.toml"
		else
			printf '%s\n' "${a/#$REPO\/scenarios/$NEW_SCENARIOS}"
		fi
		prev=$a
	done
}

# run `plant_sim ARGS...` of both builds, each into its own directory, then compare FILES
# (default: every file the base wrote). A scenario the base refuses as bad input (exit 2: a
# table it does not know yet, such as [vehicle]) is new, not changed: it is skipped, and said.
both() {
	local tag=$1; shift
	local -a files=()
	while [[ $1 != -- ]]; do files+=("$1"); shift; done
	shift
	local status=0
	"$BASE/plant_sim" "${@/#$REPO\/scenarios/$BASE_SCENARIOS}" --out "$OUT/base/$tag" >"$OUT/base/$tag.txt" 2>&1 || status=$?
	if [[ $status -eq 2 ]]; then
		echo "compare-outputs: $tag: skipped, the base refuses it (new input): $(tail -1 "$OUT/base/$tag.txt")"
		return 0
	fi
	[[ $status -eq 0 ]] || die "base: plant_sim $*: $(cat "$OUT/base/$tag.txt")"
	local -a args
	mapfile -t args < <(new_args "$@")
	[[ $WORLD -eq 1 ]] && args=("${args[@]/#--builtin/--scenario}")
	"$NEW/plant_sim" "${args[@]}" --out "$OUT/new/$tag" >"$OUT/new/$tag.txt" 2>&1 ||
		die "new: plant_sim ${args[*]}: $(cat "$OUT/new/$tag.txt")"
	[[ ${#files[@]} -gt 0 ]] || mapfile -t files < <(cd "$OUT/base/$tag" && find . -type f | sort)
	local compared=0
	for f in "${files[@]}"; do
		if [[ $f == messages.log ]] && ! cmp -s <(log_format "$OUT/base/$tag/$f") <(log_format "$OUT/new/$tag/$f"); then
			# a new flight-recorder format (a new wire protocol) changes the log by design
			echo "compare-outputs: $tag: messages.log not compared: format $(log_format "$OUT/base/$tag/$f") vs $(log_format "$OUT/new/$tag/$f")"
			continue
		fi
		cmp -s "$OUT/base/$tag/$f" "$OUT/new/$tag/$f" || die "$tag: $f differs"
		compared=$((compared + 1))
	done
	echo "compare-outputs: $tag: $compared files identical"
}
# the flight-recorder format version of a messages.log (its bytes 8..11, little-endian)
log_format() { od -An -tu4 -j8 -N4 "$1" | tr -d ' '; }
mkdir -p "$OUT/base" "$OUT/new"

for f in "$REPO"/scenarios/*.toml; do
	name=$(basename "$f" .toml)
	both "sim-$name" -- sim --scenario "$f"
done
for name in seed se3_circle; do
	both "lockstep-$name" trajectory.csv messages.log -- run --builtin "$name" --mode lockstep --name "t-compare-$name"
done
for f in "$REPO"/scenarios/*.toml; do
	grep -q '^waypoints *=' "$f" || continue
	name=$(basename "$f" .toml)
	both "reference-$name" -- reference --scenario "$f"
done
both "montecarlo" -- montecarlo --runs 6 --threads 2
both "montecarlo-estimators" -- montecarlo --scenario "$REPO/scenarios/eqf_so3.toml" --runs 3 --threads 2 --estimators truth,complementary,eqf
both "noise" -- noise --scenario "$REPO/scenarios/sensors_so3.toml" --runs 2 --gyro-noise 0.002,0.1
both "rejection" -- rejection --scenario "$REPO/scenarios/reject_so3.toml" --runs 3
# both builds replay one run: the base's lockstep seed (the new build's log is identical,
# above), or each its own when the log's format changed, copied to the same place (what
# replay prints and draws names it)
run=$OUT/replayed
for side in base new; do
	bin=$BASE
	[[ $side == new ]] && bin=$NEW
	from=$OUT/base/lockstep-seed
	[[ $(log_format "$OUT/base/lockstep-seed/messages.log") == $(log_format "$OUT/new/lockstep-seed/messages.log") ]] ||
		from=$OUT/$side/lockstep-seed
	rm -rf "$run" && cp -r "$from" "$run"
	"$bin/plant_sim" replay "$run" >"$OUT/$side/replay.txt" 2>&1 || die "$side: replay: $(cat "$OUT/$side/replay.txt")"
	"$bin/plant_sim" replay "$run" --law gt --out "$OUT/$side/whatif" >"$OUT/$side/whatif.txt" 2>&1 ||
		die "$side: replay --law gt: $(cat "$OUT/$side/whatif.txt")"
done
cmp -s "$OUT/base/replay.txt" "$OUT/new/replay.txt" || die "replay: what it prints differs"
# the what-if names the directory it wrote to; the rest of what it prints must agree
diff <(sed "s#$OUT/base/whatif#WHATIF#g" "$OUT/base/whatif.txt") <(sed "s#$OUT/new/whatif#WHATIF#g" "$OUT/new/whatif.txt") >/dev/null ||
	die "replay --law gt: what it prints differs"
for f in $(cd "$OUT/base/whatif" && find . -type f | sort); do
	cmp -s "$OUT/base/whatif/$f" "$OUT/new/whatif/$f" || die "replay what-if: $f differs"
done
echo "compare-outputs: replay: what it prints, and the what-if's files, identical"
echo "compare-outputs: PASS"
