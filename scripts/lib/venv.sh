# A private Python venv with pinned packages (sourced, not run): scripts/daqp.sh and
# scripts/mujoco.sh share it.
#
#   pinned_venv VENV LOGDIR "PACKAGES" [strict]
#
# Creates VENV with PACKAGES unless it already holds exactly them (VENV/.pinned). When pip
# fails, prints one `SKIPPED: <reason>` line and exits the calling script with 0; when the venv
# itself cannot be made, the same, or with `strict` a `FAIL:` line and exit 1 (a script whose
# only allowed skip is pip's).
pinned_venv() {
	local venv=$1 log=$2 packages=$3 strict=${4:-}
	[[ $(cat "$venv/.pinned" 2>/dev/null) == "$packages" ]] && return 0
	rm -rf "$venv"
	if ! python3 -m venv "$venv" >"$log/venv.log" 2>&1; then
		[[ -n $strict ]] && { echo "FAIL: python3 -m venv failed: $(tail -1 "$log/venv.log")" >&2; exit 1; }
		echo "SKIPPED: python3 -m venv failed: $(tail -1 "$log/venv.log")"
		exit 0
	fi
	# shellcheck disable=SC2086
	"$venv/bin/pip" install -q $packages >"$log/pip.log" 2>&1 ||
		{ echo "SKIPPED: pip could not install $packages: $(grep -m1 -E 'ERROR' "$log/pip.log" || tail -1 "$log/pip.log")"; exit 0; }
	echo "$packages" >"$venv/.pinned"
}
