#!/usr/bin/env bash
# Checks that every citation of a Markdown document in the repository points somewhere.
#
#   bash scripts/check-citations.sh              check the repository the current directory is in
#   bash scripts/check-citations.sh --self-test  check the checker on a throw-away repository
#
# Scanned: the tracked files `git ls-files '*.rs' '*.toml' '*.md' '*.sh' '*.py'` (this script
# itself excepted: its self-test writes dangling citations on purpose).
#
# A citation is a name ending in `.md`:
#   * a path with a slash (`docs/maths.md`, `../README.md`): it must be a file of the
#     repository, relative to the repository root or to the citing file's directory. A path
#     that git ignores (`out/...`, `target/...`) names a generated file, not a document, and
#     is skipped;
#   * a bare name starting with an upper-case letter (`README.md`, `MATH.md`): a file of that
#     name in the citing file's directory, at the root, or anywhere in the repository;
#   * a bare lower-case name only as a Markdown link target (`[text](name.md)`), relative to
#     the citing file (elsewhere `table.md` is more likely an output file's name than a
#     citation).
# Files of the repository: tracked files and untracked ones that git does not ignore.
# http(s) URLs are ignored.
#
# A section citation follows the file on the same line, quoted:
#   docs/maths.md, "The EqT law"      docs/maths.md §"The EqT law"      docs/maths.md, § "The EqT law"
#   docs/maths.md, "The EqT law" and "The simulations"
#   `docs/maths.md`, "The EqT law"    [the maths](docs/maths.md), "The EqT law"
# Each title must be the exact text (trimmed) of a heading `#` .. `####` of the cited file,
# outside fenced code blocks. A title whose closing quote is not on the same line is
# reported: keep a citation on one line so that it can be checked.
#
# Output: one line per dangling citation, `file:line: <citation>: <what is missing>`, and exit
# status 1; or `citations: OK (<n> checked)` (n counts each cited file and each cited
# section) and exit status 0. Exit status 2: could not check (not in a git repository).
set -euo pipefail

SELF_PATH=scripts/check-citations.sh
SEP=$'\x1f' # field separator of the extractor's records
SUB=$'\x1e' # separator of several titles within one field

CLEANUP=()
cleanup() { if ((${#CLEANUP[@]})); then rm -rf -- "${CLEANUP[@]}"; fi; }
trap cleanup EXIT

die() {
	echo "check-citations: $*" >&2
	exit 2
}

# The extractor: one record per cited .md name,
#   file SEP line SEP class SEP name SEP titles(SUB-separated) SEP unclosed-title-start
# class: path | bare | link. The last field is `!` and the title's start when its closing
# quote is not on the line, else empty.
read -r -d '' EXTRACT <<'AWK' || true
BEGIN { SEP = "\037"; SUB = "\036" }
function trim(s) { gsub(/^[ \t]+/, "", s); gsub(/[ \t]+$/, "", s); return s }
{
	line = $0
	sub(/\r$/, "", line)
	gsub(/https?:\/\/[^] \t)>"'`<]*/, " ", line)
	n = length(line)
	pos = 1
	while (pos <= n) {
		rest = substr(line, pos)
		if (!match(rest, /[-A-Za-z0-9_.\/]*[-A-Za-z0-9_]\.md/)) break
		start = pos + RSTART - 1
		name = substr(line, start, RLENGTH)
		pos = start + RLENGTH
		after = substr(line, pos)
		# `x.mdx`, `x.md5`, `x.md.bak` are not Markdown files.
		if (after ~ /^[A-Za-z0-9_]/ || after ~ /^\.[A-Za-z0-9_]/) continue
		before = (start > 2) ? substr(line, start - 2, 2) : ""
		if (name ~ /\//) cls = "path"
		else if (name ~ /^[A-Z]/) cls = "bare"
		else if (before == "](") cls = "link"
		else continue
		titles = ""; open = ""
		if (match(after, /^[`)*]*(,[ \t]*(§[ \t]*)?|[ \t]*§[ \t]*)"/)) {
			s = substr(after, RLENGTH + 1)
			while (1) {
				q = index(s, "\"")
				if (q == 0) { open = "!" trim(s); s = ""; break }
				t = trim(substr(s, 1, q - 1))
				titles = (titles == "") ? t : titles SUB t
				s = substr(s, q + 1)
				if (!match(s, /^[ \t]+and[ \t]+"/)) break
				s = substr(s, RLENGTH + 1)
			}
			pos = n - length(s) + 1
		}
		print FILENAME SEP FNR SEP cls SEP name SEP titles SEP open
	}
}
AWK

# The headings `#` .. `####` of a Markdown file, trimmed, outside fenced code blocks.
read -r -d '' HEADINGS <<'AWK' || true
/^[ \t]*(```|~~~)/ { fence = !fence; next }
fence { next }
/^(#|##|###|####)[ \t]/ {
	h = $0
	sub(/\r$/, "", h)
	sub(/^#+[ \t]+/, "", h)
	sub(/[ \t]+#+[ \t]*$/, "", h)
	gsub(/^[ \t]+/, "", h); gsub(/[ \t]+$/, "", h)
	print h
}
AWK

# Normalises a relative path (drops `.` and empty parts, resolves `..`); fails for an absolute
# path or one that leaves the repository.
normpath() {
	local path=$1 part
	local -a parts out=()
	[[ $path == /* ]] && return 1
	IFS=/ read -r -a parts <<<"$path"
	for part in "${parts[@]}"; do
		case $part in
		'' | .) ;;
		..)
			((${#out[@]})) || return 1
			unset 'out[-1]'
			;;
		*) out+=("$part") ;;
		esac
	done
	((${#out[@]})) || return 1
	(
		IFS=/
		printf '%s' "${out[*]}"
	)
}

check() {
	local root
	root=$(git rev-parse --show-toplevel 2>/dev/null) || die "not inside a git repository"
	cd "$root"

	# The repository's files, and an index by base name.
	local -A repo=() bybase=()
	local f
	while IFS= read -r -d '' f; do
		[[ -f $f ]] || continue
		repo[$f]=1
		bybase[${f##*/}]+="$f"$'\n'
	done < <(git ls-files -z --cached --others --exclude-standard)

	local -a scan=()
	while IFS= read -r -d '' f; do
		[[ $f == "$SELF_PATH" || ! -f $f ]] && continue
		scan+=("$f")
	done < <(git ls-files -z -- '*.rs' '*.toml' '*.md' '*.sh' '*.py')

	local -A headings=()
	local -a dangling=()
	local checked=0
	local file line cls name titles open dir cand target t found p ignored
	local -a targets tlist cands

	if ((${#scan[@]})); then
		while IFS="$SEP" read -r file line cls name titles open; do
			dir=${file%/*}
			[[ $dir == "$file" ]] && dir=.
			targets=()
			case $cls in
			path | link)
				# A link target is relative to the citing file; a path may be relative to
				# the root or to the citing file.
				cands=("$dir/$name")
				[[ $cls == path ]] && cands=("$name" "$dir/$name")
				for cand in "${cands[@]}"; do
					p=$(normpath "$cand") || continue
					if [[ -n ${repo[$p]:-} ]]; then
						targets=("$p")
						break
					fi
				done
				if ((${#targets[@]} == 0)); then
					# A path git ignores names a generated output, not a document: skipped.
					ignored=
					for cand in "${cands[@]}"; do
						p=$(normpath "$cand") || continue
						if git check-ignore -q -- "$p" 2>/dev/null; then
							ignored=1
							break
						fi
					done
					if [[ -n $ignored ]]; then
						continue
					fi
				fi
				;;
			bare)
				if p=$(normpath "$dir/$name") && [[ -n ${repo[$p]:-} ]]; then
					targets=("$p")
				elif [[ -n ${repo[$name]:-} ]]; then
					targets=("$name")
				elif [[ -n ${bybase[$name]:-} ]]; then
					mapfile -t targets < <(printf '%s' "${bybase[$name]}")
				fi
				;;
			esac

			tlist=()
			if [[ -n $titles ]]; then
				IFS="$SUB" read -r -a tlist <<<"$titles"
			fi

			if ((${#targets[@]} == 0)); then
				local missing="no such file in the repository"
				[[ $cls == bare ]] && missing="no file named $name in the repository"
				if ((${#tlist[@]} == 0)) && [[ -z $open ]]; then
					dangling+=("$file:$line: $name: $missing")
					checked=$((checked + 1))
				fi
				for t in "${tlist[@]}"; do
					dangling+=("$file:$line: $name, \"$t\": $missing")
					checked=$((checked + 1))
				done
				if [[ -n $open ]]; then
					dangling+=("$file:$line: $name, \"${open#!}: $missing")
					checked=$((checked + 1))
				fi
				continue
			fi

			checked=$((checked + 1))
			for t in "${tlist[@]}"; do
				checked=$((checked + 1))
				found=
				for target in "${targets[@]}"; do
					if [[ -z ${headings[$target]+set} ]]; then
						headings[$target]=$(awk "$HEADINGS" "$target")
					fi
					if grep -Fxq -- "$t" <<<"${headings[$target]}"; then
						found=1
						break
					fi
				done
				[[ -n $found ]] || dangling+=("$file:$line: $name, \"$t\": no heading \"$t\" in ${targets[*]}")
			done
			if [[ -n $open ]]; then
				checked=$((checked + 1))
				dangling+=("$file:$line: $name, \"${open#!}: section title not closed on this line (keep a citation on one line)")
			fi
		done < <(awk "$EXTRACT" "${scan[@]}")
	fi

	if ((${#dangling[@]})); then
		printf '%s\n' "${dangling[@]}"
		echo "citations: ${#dangling[@]} dangling ($checked checked)" >&2
		return 1
	fi
	echo "citations: OK ($checked checked)"
}

self_test() {
	local script tmp out rc=0 fail=0
	script=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)/$(basename "${BASH_SOURCE[0]}")
	tmp=$(mktemp -d)
	CLEANUP+=("$tmp")

	git -C "$tmp" init -q
	git -C "$tmp" config user.name "check-citations self-test"
	git -C "$tmp" config user.email "self-test@example.invalid"
	git -C "$tmp" config commit.gpgsign false
	mkdir -p "$tmp/docs" "$tmp/src"

	printf '/out\n' >"$tmp/.gitignore"
	cat >"$tmp/docs/guide.md" <<'EOF'
# Guide

## Good section

```sh
# Only in a code block
```

### Deeper section ###
EOF
	cat >"$tmp/README.md" <<'EOF'
# Fixture

See docs/guide.md, "Good section" and docs/guide.md §"Deeper section", the [guide](docs/guide.md)
and https://example.com/docs/remote.md (a URL). Runs write `out/table.md` (git-ignored).
EOF
	cat >"$tmp/docs/other.md" <<'EOF'
# Other

Back to [the guide](guide.md), "Good section" and ../README.md, "Fixture".
EOF
	cat >"$tmp/src/good.rs" <<'EOF'
//! The guide (docs/guide.md, "Good section" and "Deeper section"); README.md.
#[doc = include_str!("../README.md")]
pub struct Readme;
EOF
	cat >"$tmp/src/bad.rs" <<'EOF'
//! planted: docs/missing.md
//! planted: docs/guide.md, "No such section"
//! planted: DESIGN.md, "Anything"
//! planted: docs/guide.md, "Only in a code block"
pub fn bad() {}
EOF
	git -C "$tmp" add -A
	git -C "$tmp" commit -q --no-verify -m fixture

	out=$(cd "$tmp" && bash "$script" 2>&1) || rc=$?
	if ((rc != 1)); then
		echo "self-test: expected exit status 1 with planted citations, got $rc" >&2
		fail=1
	fi
	local want
	for want in \
		'src/bad.rs:1: docs/missing.md: no such file in the repository' \
		'src/bad.rs:2: docs/guide.md, "No such section": no heading "No such section" in docs/guide.md' \
		'src/bad.rs:3: DESIGN.md, "Anything": no file named DESIGN.md in the repository' \
		'src/bad.rs:4: docs/guide.md, "Only in a code block": no heading "Only in a code block" in docs/guide.md'; do
		if ! grep -Fxq -- "$want" <<<"$out"; then
			echo "self-test: missing report: $want" >&2
			fail=1
		fi
	done
	if grep -E '^(README\.md|docs/|src/good\.rs):' <<<"$out" >&2; then
		echo "self-test: the lines above report good citations" >&2
		fail=1
	fi

	cat >"$tmp/src/bad.rs" <<'EOF'
//! fixed: docs/guide.md, "Good section"
pub fn bad() {}
EOF
	git -C "$tmp" commit -q --no-verify -am "remove planted citations"
	rc=0
	out=$(cd "$tmp" && bash "$script" 2>&1) || rc=$?
	if ((rc != 0)) || ! grep -Eq '^citations: OK \([0-9]+ checked\)$' <<<"$out"; then
		echo "self-test: expected a pass after the fix, got status $rc:" >&2
		printf '%s\n' "$out" >&2
		fail=1
	fi

	if ((fail)); then
		echo "check-citations self-test: FAIL" >&2
		exit 1
	fi
	echo "check-citations self-test: PASS"
}

case ${1:-} in
--self-test) self_test ;;
'') check ;;
-h | --help) sed -n '2,/^set -euo/p' "${BASH_SOURCE[0]}" | sed '$d; s/^# \{0,1\}//' ;;
*) die "unknown argument: $1 (use --self-test, --help or nothing)" ;;
esac
