#!/usr/bin/env bash
# Byte-for-byte comparison of what two builds write: a refactoring must change no output byte.
#
#   bash scripts/compare-outputs.sh BASE_BIN_DIR NEW_BIN_DIR
#
# Each directory holds a plant_sim and a controller_node (e.g. two target/debug directories,
# one of them built from a `git worktree` of the base commit). Compared with cmp, file by
# file:
#   * `plant_sim sim` of every scenario in scenarios/: every file it writes (trajectory.csv,
#     summary.json, the figures);
#   * lockstep pair runs of seed and se3_circle: trajectory.csv and messages.log (a lockstep
#     log holds no clock reading and no process id);
#   * `plant_sim reference` of every waypoint scenario: every file it writes.
# Prints one line per comparison and `compare-outputs: PASS`, or the first file that differs
# and exit status 1.
set -euo pipefail
REPO=$(cd -- "$(dirname -- "${BASH_SOURCE[0]}")/.." && pwd)
[[ $# -eq 2 ]] || { echo "usage: $0 BASE_BIN_DIR NEW_BIN_DIR" >&2; exit 2; }
BASE=$(cd "$1" && pwd)
NEW=$(cd "$2" && pwd)
OUT=$(mktemp -d)
trap 'rm -rf "$OUT"' EXIT
die() { echo "compare-outputs: FAIL: $*" >&2; exit 1; }

# run `plant_sim ARGS...` of both builds, each into its own directory, then compare FILES
# (default: every file the base wrote)
both() {
	local tag=$1; shift
	local -a files=()
	while [[ $1 != -- ]]; do files+=("$1"); shift; done
	shift
	for side in base new; do
		local bin=$BASE
		[[ $side == new ]] && bin=$NEW
		"$bin/plant_sim" "$@" --out "$OUT/$side/$tag" >"$OUT/$side/$tag.txt" 2>&1 ||
			die "$side: plant_sim $*: $(cat "$OUT/$side/$tag.txt")"
	done
	[[ ${#files[@]} -gt 0 ]] || mapfile -t files < <(cd "$OUT/base/$tag" && find . -type f | sort)
	for f in "${files[@]}"; do
		cmp -s "$OUT/base/$tag/$f" "$OUT/new/$tag/$f" || die "$tag: $f differs"
	done
	echo "compare-outputs: $tag: ${#files[@]} files identical"
}
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
echo "compare-outputs: PASS"
