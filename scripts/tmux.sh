#!/usr/bin/env bash
# Provides tmux, the real terminal in which the test of `plant_sim monitor` drives the live
# view (start it, capture the pane, press q).
#
#   scripts/tmux.sh        # prints the path of a working tmux on its last line
#
# A tmux on PATH is used as it is. Otherwise Debian's tmux (and any library it lacks) is
# fetched into the private cache of scripts/lib/debian.sh (default <repo>/.toolchain) with
# `apt-get install --download-only` and unpacked with `dpkg -x`; nothing is installed
# system-wide. If the package cannot be fetched, prints one `SKIPPED: <reason>` line and
# exits 0 (the test then fails: driving the monitor in a terminal is its point).
# TMUX_FORCE_FETCH=1 fetches even when tmux is on PATH (to try the fetching path).
set -euo pipefail
REPO=$(cd -- "$(dirname -- "${BASH_SOURCE[0]}")/.." && pwd)
skip() {
	echo "SKIPPED: $*"
	exit 0
}
die() {
	echo "tmux: FAIL: $*" >&2
	exit 1
}
step() { printf '[%4ds] %s\n' "$SECONDS" "$*" >&2; }

if [[ -z ${TMUX_FORCE_FETCH:-} ]] && command -v tmux >/dev/null; then
	command -v tmux
	exit 0
fi
# shellcheck source=scripts/lib/debian.sh
source "$REPO/scripts/lib/debian.sh"
debian_fetch tmux
TMUX_BIN=$PREFIX/usr/bin/tmux
[[ -x $TMUX_BIN ]] || die "the tmux package did not provide $TMUX_BIN"
debian_fix_libs "$TMUX_BIN"
# a wrapper that finds the private libraries (libevent, libutempter) the binary may need
W=$(debian_wrapper tmux "$TMUX_BIN")
"$W" -V >/dev/null || die "$W does not run"
echo "$W"
