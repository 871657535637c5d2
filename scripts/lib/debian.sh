# Private toolchains from Debian packages, shared by scripts/cortex-m.sh and scripts/aarch64.sh
# (sourced, not run). Packages are fetched with
# `apt-get install --download-only -o Dir::Cache::archives=$DEBS` into one cache and unpacked
# into one prefix, each .deb once (then removed): the compiler both scripts use (rustc-web) is
# unpacked a single time. Nothing is installed system-wide; the one system change
# is `dpkg --add-architecture` when a script asks for a foreign architecture's package.
#
# The caller defines skip (prints `SKIPPED: ...`, exits 0), die and step, and sets REPO.
# Environment: TOOLCHAIN_CACHE=dir (default <repo>/.toolchain; CORTEX_M_CACHE is honoured too).

CACHE=${TOOLCHAIN_CACHE:-${CORTEX_M_CACHE:-$REPO/.toolchain}}
DEBS=$CACHE/debs
PREFIX=$CACHE/prefix
LOGS=$CACHE/logs
# The prefix's shared-library directories (qemu's libraries land in both).
LIBS=$PREFIX/usr/lib/x86_64-linux-gnu:$PREFIX/lib/x86_64-linux-gnu
RUSTC_PRIVATE=$PREFIX/usr/bin/rustc

# The rustc the repository needs (workspace rust-version), e.g. 1.89.
NEED_RUST=$(sed -n 's/^rust-version *= *"\([0-9.]*\)".*/\1/p' "$REPO/Cargo.toml" | head -1)
NEED_RUST=${NEED_RUST:-1.85}

mkdir -p "$CACHE" "$LOGS" "$DEBS" "$PREFIX/.unpacked"
# The cache (about 2 GiB with both scripts' toolchains) must never be committed, whatever the repository's .gitignore says.
[[ -f $CACHE/.gitignore ]] ||
	printf '# Written by scripts/lib/debian.sh: the private toolchain cache is never committed.\n*\n' >"$CACHE/.gitignore"
# One script at a time per cache.
exec 9>"$CACHE/.lock"
flock 9

# True when apt's lists offer every package named, and a rustc-web at least $NEED_RUST.
debian_lists_ok() {
	local p cand
	for p in "$@"; do
		cand=$(apt-cache policy "$p" 2>/dev/null | sed -n 's/^ *Candidate: *//p')
		[[ -n $cand && $cand != "(none)" ]] || return 1
		if [[ $p == rustc-web* ]] && ! dpkg --compare-versions "$cand" ge "$NEED_RUST"; then
			return 1
		fi
	done
}

# Enables a foreign architecture for apt (arm64, ...) when it is not yet; skips when that is
# not possible (not root).
debian_architecture() {
	dpkg --print-foreign-architectures 2>/dev/null | grep -qx "$1" && return 0
	[[ $(id -u) == 0 ]] || skip "dpkg --add-architecture $1 needs root (run once as root, or install the packages by hand)"
	step "dpkg --add-architecture $1"
	dpkg --add-architecture "$1" || skip "dpkg --add-architecture $1 failed"
	rm -f "$CACHE/.lists-for-"*
}

# The cached rustc must still satisfy the repository's rust-version (else fetch again).
debian_check_cached_rustc() {
	[[ -x $RUSTC_PRIVATE ]] || return 0
	local have
	have=$(LD_LIBRARY_PATH=$LIBS "$RUSTC_PRIVATE" --version 2>/dev/null | awk '{print $2}' || true)
	if [[ -z $have ]] || ! dpkg --compare-versions "$have" ge "$NEED_RUST"; then
		step "cached rustc '${have:-none}' is older than $NEED_RUST: fetching again"
		rm -rf "$PREFIX" "$DEBS"
		mkdir -p "$DEBS" "$PREFIX/.unpacked"
	fi
}

# Downloads the packages and the dependencies this machine lacks into $DEBS, and unpacks
# every .deb not unpacked yet into $PREFIX. A second call with the same packages does
# nothing. Skips (exit 0) when apt cannot provide them.
debian_fetch() {
	local set_id done
	set_id=$(printf '%s\n' "$@" | sort | md5sum | cut -c1-12)
	done=$CACHE/.fetched-$set_id
	debian_check_cached_rustc
	if [[ ! -f $done ]]; then
		command -v apt-get >/dev/null && command -v dpkg >/dev/null ||
			skip "apt-get/dpkg not found: the toolchain comes from Debian packages"
		if ! debian_lists_ok "$@"; then
			step "apt-get update (the package lists lack $* or a rustc-web >= $NEED_RUST)"
			# A failing extra repository makes update exit non-zero: judge by the lists instead.
			apt-get update >"$LOGS/apt-update.log" 2>&1 || true
			if ! debian_lists_ok "$@"; then
				why=$(grep -E '^(E|W):' "$LOGS/apt-update.log" | tail -1 || true)
				skip "apt-get update did not provide $* with rustc-web >= $NEED_RUST${why:+ ($why)}"
			fi
		fi
		step "downloading $* and their missing dependencies (apt-get --download-only)"
		mkdir -p "$DEBS/partial"
		if ! apt-get install -y --download-only --no-install-recommends \
			-o Dir::Cache::archives="$DEBS" "$@" >"$LOGS/apt-download.log" 2>&1; then
			skip "apt-get could not download $*: $(grep -E '^E:' "$LOGS/apt-download.log" | tail -1 || tail -1 "$LOGS/apt-download.log")"
		fi
		rm -rf "$DEBS/partial" "$DEBS/lock"
		local p
		for p in "$@"; do
			p=${p%%:*}
			compgen -G "$DEBS/${p}_*.deb" >/dev/null ||
				skip "apt-get downloaded no $p package (is it installed system-wide? see $LOGS/apt-download.log)"
		done
		printf '%s\n' "$@" >"$done"
	fi
	local d n=0
	for d in "$DEBS"/*.deb; do
		[[ -f $d ]] || continue # none left: all unpacked and removed
		if [[ -f $PREFIX/.unpacked/$(basename "$d") ]]; then
			rm -f "$d" # fetched again for another package set, unpacked before
			continue
		fi
		debian_unpack "$d"
		n=$((n + 1))
	done
	((n == 0)) || step "unpacked $n packages into $PREFIX"
}

# Unpacks one .deb into $PREFIX (as `dpkg -x` does), marks it unpacked and removes it: the
# prefix is the cache, the archive is not needed again. The compiler's and the tools' sources
# of rust-web-src (build-std reads only library/) and the documentation are left out while
# unpacking, so the disk never holds them. A failure (a full disk) stops the script.
debian_unpack() {
	local d=$1
	dpkg-deb --fsys-tarfile "$d" | tar -x -C "$PREFIX" --no-same-owner \
		--anchored --no-wildcards-match-slash --exclude='./usr/src/rustc-*/src' --exclude='./usr/src/rustc-*/compiler' \
		--exclude='./usr/src/rustc-*/tests' --exclude='./usr/share/doc' ||
		die "could not unpack $(basename "$d") into $PREFIX ($(df -h --output=avail "$PREFIX" | tail -1 | tr -d ' ') free on its disk)"
	touch "$PREFIX/.unpacked/$(basename "$d")"
	rm -f "$d"
}

# Writes $CACHE/bin/NAME, a wrapper that runs the private binary BIN with the prefix's
# libraries, and prints its path.
debian_wrapper() {
	local w=$CACHE/bin/$1
	mkdir -p "$CACHE/bin"
	printf '#!/bin/sh\nLD_LIBRARY_PATH=%s${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH} exec %s "$@"\n' "$LIBS" "$2" >"$w"
	chmod +x "$w"
	echo "$w"
}

# Shared libraries a private binary cannot find.
debian_missing_libs() { LD_LIBRARY_PATH=$LIBS ldd "$1" 2>/dev/null | sed -n 's/^\s*\(\S*\) => not found.*/\1/p'; }

# Libraries the system may hold only through packages apt assumed installed: when ldd finds
# one missing for a private binary, fetch its package (named by Debian's soname rule:
# libfoo.so.1 -> libfoo1, libnl-3.so.200 -> libnl-3-200) with `apt-get download` and unpack
# it too.
debian_fix_libs() {
	local bin lib base ver pkg missing=()
	for bin in "$@"; do
		mapfile -t -O "${#missing[@]}" missing < <(debian_missing_libs "$bin")
	done
	((${#missing[@]})) || return 0
	step "private binaries lack ${missing[*]}: fetching their packages"
	for lib in $(printf '%s\n' "${missing[@]}" | sort -u); do
		base=${lib%%.so.*}
		ver=${lib##*.so.}
		ver=${ver%%.*}
		if [[ $base =~ [0-9]$ ]]; then pkg=$base-$ver; else pkg=$base$ver; fi
		pkg=${pkg,,}
		(cd "$DEBS" && apt-get download "$pkg" >>"$LOGS/apt-download.log" 2>&1) ||
			skip "could not download $pkg (for $lib): $(tail -1 "$LOGS/apt-download.log")"
		debian_unpack "$(compgen -G "$DEBS/${pkg}_*.deb" | head -1)"
	done
	for bin in "$@"; do
		[[ -z $(debian_missing_libs "$bin") ]] || die "$bin still lacks: $(debian_missing_libs "$bin" | tr '\n' ' ')"
	done
}

# A wrapper that runs the private rustc with its own libraries (cargo takes it as RUSTC).
debian_rustc_wrapper() {
	local w=$CACHE/bin/rustc
	mkdir -p "$CACHE/bin"
	printf '#!/bin/sh\nLD_LIBRARY_PATH=%s${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH} exec %s "$@"\n' \
		"$PREFIX/usr/lib:$LIBS" "$RUSTC_PRIVATE" >"$w"
	chmod +x "$w"
	echo "$w"
}
