#!/usr/bin/env python3
"""Who depends on whom among the workspace's crates, from `cargo metadata` (direct normal
dependencies on crates of the workspace).

    cargo metadata --format-version 1 --no-deps --offline | python3 scripts/crate-arrows.py
        prints the block docs/architecture.md carries: one line per crate others depend on,
        `crate ◀── dependents`
    ... | python3 scripts/crate-arrows.py --check docs/architecture.md [README.md ...]
        requires the first page's block to be that block, and every page's crate table's
        last column ("depends on (ours)") to name exactly each crate's dependencies, the
        embedded workspaces' rows (`embedded/NAME`) included, from their own manifests;
        prints each difference and exits 1 if there is one

scripts/check-arrows.sh runs the check in CI.
"""
import json
import re
import sys

meta = json.load(sys.stdin)
members = set(meta["workspace_members"])
packages = [p for p in meta["packages"] if p["id"] in members]
ours = {p["name"] for p in packages}
deps = {
    p["name"]: [
        d["name"]
        for d in p["dependencies"]
        if d["kind"] is None and d["name"] in ours and d["name"] != p["name"]
    ]
    for p in packages
}
# alphabetical: cargo metadata's own order differs between checkouts
order = sorted(p["name"] for p in packages)
width = max(len(n) for n in ours) + 2
block = [
    f"{name.ljust(width)}◀── {', '.join(n for n in order if name in deps[n])}"
    for name in order
    if any(name in deps[n] for n in order)
]

if len(sys.argv) == 1:
    print("\n".join(block))
    sys.exit(0)
if len(sys.argv) < 3 or sys.argv[1] != "--check":
    sys.exit(__doc__)


def check_table(path, page, bad):
    """The crate table: | `name` | ... | depends on (ours) |."""
    rows = {}
    for l in page:
        m = re.match(r"^\| `((?:eqtrack-[a-z-]+|[a-z_]+))` \|(.*)\|\s*$", l)
        if m and m.group(1) in ours:
            rows[m.group(1)] = set(re.findall(r"`((?:eqtrack-[a-z-]+|[a-z_]+))`", m.group(2).split("|")[-1]))
    for name in order:
        if name == "pair_tests":
            continue  # tests/: only dev-dependencies
        if name not in rows:
            bad.append(f"{path}: the crate table has no row for `{name}`")
        elif rows[name] != set(deps[name]):
            bad.append(
                f"{path}: the crate table says `{name}` depends on {sorted(rows[name]) or 'nothing of ours'}; "
                f"cargo metadata says {sorted(deps[name]) or 'nothing of ours'}"
            )


def check_embedded(path, page, bad):
    """Rows `| `embedded/NAME` | ... | depends on |`: what NAME's own manifest depends on."""
    import subprocess

    for l in page:
        m = re.match(r"^\| `embedded/([a-z-]+)` \|(.*)\|\s*$", l)
        if not m:
            continue
        name = m.group(1)
        said = set(re.findall(r"`((?:eqtrack-[a-z-]+|[a-z_]+))`", m.group(2).split("|")[-1])) & ours
        out = subprocess.run(
            ["cargo", "metadata", "--format-version", "1", "--no-deps", "--offline",
             "--manifest-path", f"embedded/{name}/Cargo.toml"],
            capture_output=True, text=True,
        )
        if out.returncode != 0:
            bad.append(f"{path}: cargo metadata failed for embedded/{name}: {out.stderr.strip()}")
            continue
        pkg = next(p for p in json.loads(out.stdout)["packages"] if p["name"] == name)
        real = {d["name"] for d in pkg["dependencies"] if d["kind"] is None and d["name"] in ours}
        if said != real:
            bad.append(
                f"{path}: `embedded/{name}` is said to depend on {sorted(said)}; "
                f"its manifest says {sorted(real)}"
            )


bad = []
page = open(sys.argv[2], encoding="utf-8").read().splitlines()
start = next((i for i, l in enumerate(page) if l.startswith("who depends on whom")), None)
if start is None:
    bad.append("no \"who depends on whom\" block")
else:
    lines = page[start + 1 :]
    while lines and not lines[0].strip():
        lines.pop(0)
    documented = []
    for l in lines:
        if not l.strip():
            break
        documented.append(l)
    if documented != block:
        bad.append(f"{sys.argv[2]}: the \"who depends on whom\" block differs; it should read:\n" + "\n".join(block))
for path in sys.argv[2:]:
    check_table(path, open(path, encoding="utf-8").read().splitlines(), bad)
    check_embedded(path, open(path, encoding="utf-8").read().splitlines(), bad)
for problem in bad:
    print(f"docs: {problem}")
sys.exit(1 if bad else 0)
