#!/usr/bin/env bash
# The dependency arrows docs/architecture.md promises, checked from `cargo tree` (normal
# dependencies, resolved for the crate alone):
#   * export links none of iceoryx2, plotters, ratatui, rayon, hdrhistogram, nor plant_sim,
#     link or controller_node: the offline exporter needs only the recorder and the wire;
#   * recorder depends, of our crates, only on ipc_types (and what ipc_types needs): a
#     recording is read without the plant, the controller process or a transport;
#   * no control process (plant_sim, controller_node, link) links mcap, and export does;
#   * the wire (ipc_types) depends on no crate of ours: it owns its codes, and link::wire
#     converts them to and from the maths crate's types.
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

# check DIR: prints one line per broken rule; status 1 if any
check() {
	local dir=$1 bad=0 p
	local export_tree recorder_tree wire_tree
	export_tree=$(tree "$dir" export)
	recorder_tree=$(tree "$dir" recorder)
	wire_tree=$(tree "$dir" ipc_types)
	[[ -n $export_tree && -n $recorder_tree && -n $wire_tree ]] || { echo "cargo tree failed in $dir" >&2; return 2; }
	for p in controller estimator scenario link recorder plant_sim controller_node; do
		if grep -qx "$p" <<<"$wire_tree"; then
			echo "arrow: ipc_types depends on $p (the wire owns its codes; conversions live in link::wire)"
			bad=1
		fi
	done
	for p in iceoryx2 plotters ratatui rayon hdrhistogram plant_sim link controller_node; do
		if grep -qx "$p" <<<"$export_tree"; then
			echo "arrow: export depends on $p (the exporter needs only recorder and ipc_types)"
			bad=1
		fi
	done
	for p in plant_sim link controller_node scenario estimator export; do
		if grep -qx "$p" <<<"$recorder_tree"; then
			echo "arrow: recorder depends on $p (it may know the wire only)"
			bad=1
		fi
	done
	for p in plant_sim controller_node link; do
		if tree "$dir" "$p" | grep -qx mcap; then
			echo "arrow: $p links mcap (only the export crate may)"
			bad=1
		fi
	done
	grep -qx mcap <<<"$export_tree" || { echo "the check cannot see mcap in export's tree" >&2; return 2; }
	return $bad
}

if [[ ${1:-} != --self-test ]]; then
	check "$REPO"
	echo "arrows: OK (export, recorder, the wire, mcap)"
	exit 0
fi

# Self-test: each planted arrow must be caught.
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
(cd "$REPO" && git ls-files -z | xargs -0 tar -cf - 2>/dev/null) | (cd "$work" && tar -xf -)
check "$work" >/dev/null || { echo "check-arrows self-test: the unplanted copy fails" >&2; exit 1; }
plant() { # plant FILE LINE: add LINE to FILE's [dependencies], check, restore
	local file=$work/$1 line=$2 out
	cp "$file" "$file.orig"
	awk -v add="$line" '{ print } !done && $0 == "[dependencies]" { print add; done = 1 }' "$file.orig" >"$file"
	if out=$(check "$work"); then
		echo "check-arrows self-test: \`$line\` in $1 was not caught" >&2
		exit 1
	fi
	echo "caught: $line in $1 -> $(head -1 <<<"$out")"
	mv "$file.orig" "$file"
}
plant export/Cargo.toml 'plant_sim = { path = "../plant_sim" }'
plant export/Cargo.toml 'rayon = "1"'
plant recorder/Cargo.toml 'link = { path = "../link" }'
plant ipc_types/Cargo.toml 'controller = { path = "../controller" }'
plant controller_node/Cargo.toml 'mcap = { version = "0.26", default-features = false }'
echo "check-arrows self-test: every planted arrow caught"
