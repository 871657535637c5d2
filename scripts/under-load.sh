#!/usr/bin/env bash
# Runs a command while a CPU hog keeps every core busy: one `yes` per core (`nproc`), at
# normal priority, killed when the command ends. Exits with the command's status.
#
#   bash scripts/under-load.sh cargo test --workspace
set -euo pipefail
[[ $# -gt 0 ]] || { echo "usage: $0 COMMAND [ARGS...]" >&2; exit 2; }
hogs=()
stop_hogs() { [[ ${#hogs[@]} -eq 0 ]] || kill "${hogs[@]}" 2>/dev/null || true; }
trap stop_hogs EXIT
for _ in $(seq "$(nproc)"); do
	yes >/dev/null &
	hogs+=($!)
done
echo "under-load: ${#hogs[@]} CPU hogs (yes) running beside: $*" >&2
"$@"
