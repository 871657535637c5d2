#!/usr/bin/env bash
# The dependency arrows docs/architecture.md promises, checked from `cargo tree` (normal
# dependencies, resolved for the crate alone):
#   * export links none of iceoryx2, plotters, ratatui, rayon, hdrhistogram, nor plant_sim,
#     link or controller_node: the offline exporter needs only the channels, the recorder and
#     the wire; channels (the messages the export and the live bridge share) none of those
#     either, nor mcap, tungstenite or tokio;
#   * recorder depends, of our crates, only on ipc_types (and what ipc_types needs): a
#     recording is read without the plant, the controller process or a transport;
#   * no control process (plant_sim, controller_node, link) links mcap, and export does; none
#     links the live bridge (live, tungstenite, channels): plant_sim runs eqtrack-live;
#   * the wire (ipc_types) depends on no crate of ours: it owns its codes, and link::wire
#     converts them to and from the maths crate's types;
#   * the plant process's library (plant) depends on no crate of the controller process
#     (controller_node, control_cycle), and the plant_sim command line not on controller_node:
#     the two processes meet only on the wire;
#   * fuzz depends on libraries, not on a process's crate (plant_sim, controller_node);
#   * docs/architecture.md's crate table and "who depends on whom" block, and README.md's
#     crate map, say what `cargo metadata` says, the embedded workspaces' rows included
#     (scripts/crate-arrows.py --check).
#
#   bash scripts/check-arrows.sh              check this repository
#   bash scripts/check-arrows.sh --self-test  plant each forbidden arrow in a copy of the
#                                             manifests and require the check to fail on it
set -euo pipefail
REPO=$(cd -- "$(dirname -- "${BASH_SOURCE[0]}")/.." && pwd)

# the packages in CRATE's normal dependency tree (names only), run in $1
tree() {
	(cd "$1" && cargo tree --offline -e normal -p "$2" --prefix none --format '{p}' 2>/dev/null) |
		awk '{print $1}' | sort -u
}

# check DIR [--no-docs]: prints one line per broken rule; status 1 if any, 2 if a tree could
# not be read (an unreadable tree must not pass as "no arrow")
check() {
	local dir=$1 bad=0 p c
	local -A trees
	for c in export channels live recorder ipc_types plant plant_sim fuzz controller_node link flight_tools; do
		trees[$c]=$(tree "$dir" "$c")
		[[ -n ${trees[$c]} ]] || { echo "cargo tree failed for $c in $dir" >&2; return 2; }
	done
	# our crates: every member of the workspace
	local ours
	ours=$( (cd "$dir" && cargo metadata --format-version 1 --no-deps --offline) |
		python3 -c 'import json,sys; m=json.load(sys.stdin); print("\n".join(p["name"] for p in m["packages"]))')
	[[ -n $ours ]] || { echo "cargo metadata failed in $dir" >&2; return 2; }
	for p in $ours; do
		if [[ $p != ipc_types ]] && grep -qx "$p" <<<"${trees[ipc_types]}"; then
			echo "arrow: ipc_types depends on $p (the wire owns its codes; conversions live in link::wire)"
			bad=1
		fi
		if [[ $p != recorder && $p != ipc_types ]] && grep -qx "$p" <<<"${trees[recorder]}"; then
			echo "arrow: recorder depends on $p (it may know the wire only)"
			bad=1
		fi
	done
	for p in iceoryx2 plotters ratatui rayon hdrhistogram plant plant_sim studies flight_tools floors link controller_node control_cycle live; do
		if grep -qx "$p" <<<"${trees[export]}"; then
			echo "arrow: export depends on $p (the exporter needs only channels, recorder and ipc_types)"
			bad=1
		fi
		if grep -qx "$p" <<<"${trees[channels]}"; then
			echo "arrow: channels depends on $p (the channels need only recorder and ipc_types)"
			bad=1
		fi
	done
	for p in mcap tungstenite tokio; do
		if grep -qx "$p" <<<"${trees[channels]}"; then
			echo "arrow: channels links $p (the channels are messages: no file format, network or runtime)"
			bad=1
		fi
	done
	for p in plant plant_sim controller_node control_cycle mcap tokio; do
		if grep -qx "$p" <<<"${trees[live]}"; then
			echo "arrow: live depends on $p (the bridge reads the boards through link and the messages from channels)"
			bad=1
		fi
	done
	for p in controller_node control_cycle; do
		if grep -qx "$p" <<<"${trees[plant]}"; then
			echo "arrow: plant depends on $p (the plant process knows the controller only through the wire)"
			bad=1
		fi
	done
	if grep -qx controller_node <<<"${trees[plant_sim]}"; then
		echo "arrow: plant_sim depends on controller_node (replay runs control_cycle, the controller's library)"
		bad=1
	fi
	for p in plant_sim controller_node; do
		if grep -qx "$p" <<<"${trees[fuzz]}"; then
			echo "arrow: fuzz depends on $p (a process's crate; fuzz the libraries)"
			bad=1
		fi
	done
	for p in plant_sim controller_node link plant flight_tools; do
		if grep -qx mcap <<<"${trees[$p]}"; then
			echo "arrow: $p links mcap (only the export crate may)"
			bad=1
		fi
		for q in live tungstenite channels; do
			if grep -qx "$q" <<<"${trees[$p]}"; then
				echo "arrow: $p links $q (the live bridge is a process of its own: plant_sim runs eqtrack-live)"
				bad=1
			fi
		done
	done
	grep -qx mcap <<<"${trees[export]}" || { echo "the check cannot see mcap in export's tree" >&2; return 2; }
	grep -qx tungstenite <<<"${trees[live]}" || { echo "the check cannot see tungstenite in live's tree" >&2; return 2; }
	if [[ ${2:-} != --no-docs ]]; then
		(cd "$dir" && cargo metadata --format-version 1 --no-deps --offline | python3 scripts/crate-arrows.py --check docs/architecture.md README.md) || bad=1
	fi
	return $bad
}

if [[ ${1:-} != --self-test ]]; then
	check "$REPO"
	echo "arrows: OK (export, channels, live, recorder, the wire, mcap, plant, fuzz, and the docs' block)"
	exit 0
fi

# Self-test: each planted arrow must be caught.
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
# the working tree's files (tracked, and new ones git does not ignore)
(cd "$REPO" && git ls-files -z --cached --others --exclude-standard | xargs -0 tar -cf - 2>/dev/null) | (cd "$work" && tar -xf -)
check "$work" >/dev/null || { echo "check-arrows self-test: the unplanted copy fails" >&2; exit 1; }
# plant FILE LINE WANT [--no-docs]: add LINE to FILE's [dependencies], check (the rule
# checks alone with --no-docs), require a failure with a line that holds WANT, restore
plant() {
	local file=$work/$1 line=$2 want=$3 out
	cp "$file" "$file.orig"
	awk -v add="$line" '{ print } !done && $0 == "[dependencies]" { print add; done = 1 }' "$file.orig" >"$file"
	if out=$(check "$work" "${4:-}"); then
		echo "check-arrows self-test: \`$line\` in $1 was not caught" >&2
		exit 1
	fi
	grep -qF "$want" <<<"$out" || {
		echo "check-arrows self-test: \`$line\` in $1 was caught by the wrong rule: $out" >&2
		exit 1
	}
	echo "caught: $line in $1 -> $(grep -F "$want" <<<"$out" | head -1)"
	mv "$file.orig" "$file"
}
plant export/Cargo.toml 'plant_sim = { path = "../plant_sim" }' "export depends on plant_sim" --no-docs
plant export/Cargo.toml 'plant = { path = "../plant" }' "export depends on plant" --no-docs
plant export/Cargo.toml 'rayon = "1"' "export depends on rayon" --no-docs
plant export/Cargo.toml 'iceoryx2 = "=0.10.0"' "export depends on iceoryx2" --no-docs
plant channels/Cargo.toml 'link = { path = "../link" }' "channels depends on link" --no-docs
plant channels/Cargo.toml 'mcap = { version = "0.26", default-features = false }' "channels links mcap" --no-docs
plant live/Cargo.toml 'plant = { path = "../plant" }' "live depends on plant" --no-docs
plant plant_sim/Cargo.toml 'tungstenite = "0.30"' "plant_sim links tungstenite" --no-docs
plant controller_node/Cargo.toml 'live = { path = "../live" }' "controller_node links live" --no-docs
plant ipc_types/Cargo.toml 'eqtrack-allocation = { path = "../allocation" }' "ipc_types depends on eqtrack-allocation" --no-docs
plant recorder/Cargo.toml 'eqtrack-controller = { path = "../controller" }' "recorder depends on eqtrack-controller" --no-docs
plant recorder/Cargo.toml 'link = { path = "../link" }' "recorder depends on link" --no-docs
plant ipc_types/Cargo.toml 'eqtrack-controller = { path = "../controller" }' "ipc_types depends on eqtrack-controller" --no-docs
plant controller_node/Cargo.toml 'mcap = { version = "0.26", default-features = false }' "controller_node links mcap" --no-docs
plant plant/Cargo.toml 'controller_node = { path = "../controller_node" }' "plant depends on controller_node" --no-docs
plant plant/Cargo.toml 'control_cycle = { path = "../control_cycle" }' "plant depends on control_cycle" --no-docs
plant plant_sim/Cargo.toml 'controller_node = { path = "../controller_node" }' "plant_sim depends on controller_node" --no-docs
plant fuzz/Cargo.toml 'plant_sim = { path = "../plant_sim" }' "fuzz depends on plant_sim" --no-docs
plant fuzz/Cargo.toml 'controller_node = { path = "../controller_node" }' "fuzz depends on controller_node" --no-docs
# an arrow no rule forbids: only the docs' block can catch it
plant studies/Cargo.toml 'recorder = { path = "../recorder" }' "docs: docs/architecture.md: the \"who depends on whom\" block differs"
# an embedded workspace's dependency the README does not name
plant embedded/nostd-check/Cargo.toml 'scenario = { path = "../../scenario" }' "README.md: \`embedded/nostd-check\` is said to depend on"
echo "check-arrows self-test: every planted arrow caught"
