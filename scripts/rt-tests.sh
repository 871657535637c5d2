#!/usr/bin/env bash
# Provides cyclictest (Debian's rt-tests), the operating-system floor of `plant_sim bench-loop`.
#
#   scripts/rt-tests.sh        # prints the path of a working cyclictest on its last line
#
# A cyclictest on PATH is used as it is. Otherwise Debian's rt-tests (and any library it
# lacks) is fetched into the private cache of scripts/lib/debian.sh (default <repo>/.toolchain)
# with `apt-get install --download-only` and unpacked with `dpkg -x`; nothing is installed
# system-wide. Pass the path to bench-loop: `plant_sim bench-loop --cyclictest PATH`.
# If the package cannot be fetched, prints one `SKIPPED: <reason>` line and exits 0.
set -euo pipefail
REPO=$(cd -- "$(dirname -- "${BASH_SOURCE[0]}")/.." && pwd)
skip() {
	echo "SKIPPED: $*"
	exit 0
}
die() {
	echo "rt-tests: FAIL: $*" >&2
	exit 1
}
step() { printf '[%4ds] %s\n' "$SECONDS" "$*" >&2; }

if command -v cyclictest >/dev/null; then
	command -v cyclictest
	exit 0
fi
# shellcheck source=scripts/lib/debian.sh
source "$REPO/scripts/lib/debian.sh"
debian_fetch rt-tests
CYCLICTEST=$PREFIX/usr/bin/cyclictest
[[ -x $CYCLICTEST ]] || die "rt-tests did not provide $CYCLICTEST"
debian_fix_libs "$CYCLICTEST"
# a wrapper that finds the private libraries (libnuma) the binary may need
W=$(debian_wrapper cyclictest "$CYCLICTEST")
"$W" --help >/dev/null 2>&1 || [[ $? -le 1 ]] || die "$W does not run"
echo "$W"
