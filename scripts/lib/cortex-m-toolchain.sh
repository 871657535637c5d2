# The Cortex-M toolchain of scripts/cortex-m.sh and scripts/pil.sh (sourced, not run): Debian's
# rustc-web with its library sources (for `-Z build-std=core`) and qemu-system-arm, privately
# in the cache of scripts/lib/debian.sh, and the rustup toolchain's rust-lld as the linker.
#
# The caller defines skip, die and step, sets REPO, PACKAGES and FW (the firmware's directory),
# and gets QEMU, LLD, HOST_SYSROOT and fw_env (runs a command in FW with the private toolchain).

# shellcheck source=scripts/lib/debian.sh
source "$REPO/scripts/lib/debian.sh"
QEMU=$PREFIX/usr/bin/qemu-system-arm
debian_fetch "${PACKAGES[@]}"
debian_fix_libs "$QEMU" "$RUSTC_PRIVATE"
step "toolchain: in $CACHE"

# build-std reads the library sources from <sysroot>/lib/rustlib/src/rust (the package links
# it to /usr/src/rustc-<version>; make sure the link exists).
SRC_LINK=$PREFIX/usr/lib/rustlib/src/rust
if [[ ! -d $SRC_LINK/library/core ]]; then
	src=$(ls -d "$PREFIX"/usr/src/rustc-* 2>/dev/null | head -1)
	[[ -n $src && -d $src/library/core ]] || die "rust-web-src did not provide library sources under $PREFIX/usr/src"
	mkdir -p "$(dirname "$SRC_LINK")"
	ln -sfn "$src" "$SRC_LINK"
fi

# The linker: rust-lld from the machine's rustup toolchain (Debian's rustc-web has none).
HOST_SYSROOT=$(env -u RUSTC rustc --print sysroot 2>/dev/null || true)
LLD=$(ls "$HOST_SYSROOT"/lib/rustlib/*/bin/rust-lld 2>/dev/null | head -1 || true)
[[ -n $LLD ]] || LLD=$(ls "${RUSTUP_HOME:-$HOME/.rustup}"/toolchains/*/lib/rustlib/*/bin/rust-lld 2>/dev/null | head -1 || true)
[[ -n $LLD ]] || die "rust-lld not found (expected in the rustup toolchain: $HOST_SYSROOT/lib/rustlib/<host>/bin)"

echo "toolchain: $(LD_LIBRARY_PATH=$LIBS "$RUSTC_PRIVATE" --version); $(LD_LIBRARY_PATH=$LIBS "$QEMU" --version | head -1); linker $LLD"

# Only the firmware's commands see the private toolchain; RUSTFLAGS from the caller would
# replace the config's `-Tlink.x`, so they are dropped.
fw_env() {
	(cd "$FW" && exec env -u RUSTFLAGS -u CARGO_ENCODED_RUSTFLAGS -u CARGO_BUILD_RUSTFLAGS \
		-u CARGO_BUILD_TARGET \
		CARGO_TARGET_DIR="$FW/target" \
		LD_LIBRARY_PATH="$LIBS${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}" \
		PATH="$PREFIX/usr/bin:$PATH" \
		RUSTC="$RUSTC_PRIVATE" RUSTC_BOOTSTRAP=1 \
		CARGO_TARGET_THUMBV7EM_NONE_EABIHF_LINKER="$LLD" \
		"$@")
}

