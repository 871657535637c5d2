#!/usr/bin/env bash
# The Python package, tested as a user gets it: a venv, `pip install ./python` (maturin builds
# the abi3 wheel through PEP 517 and pip installs it), then pytest over python/tests:
# simulate and montecarlo against the command line bit for bit, the building blocks, bad
# inputs, a two-worker local Ray cluster, a Ray worker killed mid-sweep, and the Ray Tune
# example with a tiny budget.
#
#   scripts/python.sh [pytest args...]
#
# The venv is cached in <repo>/.toolchain/python-venv (TOOLCHAIN_CACHE overrides). If the
# packages cannot be installed, prints one `SKIPPED: <reason>` line and exits 0. The tests
# compare with target/debug/plant_sim (built if missing; PLANT_SIM overrides). Exit 1 on
# failure.
set -euo pipefail
REPO=$(cd -- "$(dirname -- "${BASH_SOURCE[0]}")/.." && pwd)
CACHE=${TOOLCHAIN_CACHE:-$REPO/.toolchain}
VENV=$CACHE/python-venv
LOGS=$CACHE/logs
PACKAGES=("maturin>=1.9,<2" numpy pytest pandas matplotlib "ray[default,tune]==2.60.0")
die() {
	echo "python: FAIL: $*" >&2
	exit 1
}
mkdir -p "$CACHE" "$LOGS"
[[ -f $CACHE/.gitignore ]] || printf '*\n' >"$CACHE/.gitignore"

if ! "$VENV/bin/python" -c "import maturin, numpy, pytest, pandas, matplotlib, ray.tune" 2>/dev/null; then
	rm -rf "$VENV"
	python3 -m venv "$VENV" >"$LOGS/python-venv.log" 2>&1 ||
		{ echo "SKIPPED: python3 -m venv failed: $(tail -1 "$LOGS/python-venv.log")"; exit 0; }
	"$VENV/bin/pip" install -q "${PACKAGES[@]}" >"$LOGS/python-pip.log" 2>&1 ||
		{ echo "SKIPPED: pip could not install ${PACKAGES[*]}: $(grep -m1 ERROR "$LOGS/python-pip.log" || tail -1 "$LOGS/python-pip.log")"; exit 0; }
fi

echo "python: building and installing the package (pip install ./python)"
# pip runs maturin in an isolated build environment; the build shares the workspace's target/
"$VENV/bin/pip" install --force-reinstall --no-deps ./python >"$LOGS/python-build.log" 2>&1 ||
	{ tail -30 "$LOGS/python-build.log" >&2; die "pip install ./python failed (log: $LOGS/python-build.log)"; }
grep -m1 -o 'eqtrack-[^ ]*\.whl' "$LOGS/python-build.log" | head -1 | sed 's/^/python: built /' || true

TARGET=$(cd "$REPO" && cargo metadata --format-version 1 --no-deps |
	python3 -c 'import json, sys; print(json.load(sys.stdin)["target_directory"])')
export PLANT_SIM=${PLANT_SIM:-$TARGET/debug/plant_sim}
[[ -x $PLANT_SIM ]] || (cd "$REPO" && cargo build --locked -p plant_sim >"$LOGS/python-plant-sim.log" 2>&1) ||
	die "cannot build plant_sim (log: $LOGS/python-plant-sim.log)"

# from the repository's root, so that `import eqtrack` finds the installed package, not the
# source folder python/eqtrack (which has no compiled module)
cd "$REPO"
export RAY_AUTH_MODE=disabled RAY_USAGE_STATS_ENABLED=0
"$VENV/bin/python" -m pytest -q -p no:cacheprovider python/tests "$@" || die "pytest failed"
echo "python: PASS"
