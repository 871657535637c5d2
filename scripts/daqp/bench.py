"""DAQP beside eqtrack on the same allocation problems (scripts/daqp.sh; docs/vehicles.md,
"Bounded time").

    python bench.py PROBLEMS.csv EQTRACK.jsonl

PROBLEMS.csv and EQTRACK.jsonl come from `cargo run --release -p eqtrack-allocation --example peer`:
saturated hexarotor and ROV demands, each solved cold, and a saturating trajectory, each tick
warm. DAQP solves each problem two ways, posed on residual variables so that its row
normalisation leaves every least-squares level as eqtrack means it (scripts/daqp/resolve.py):

* the torque stage alone: bounds and s = B_tau u - tau hard, s = 0 soft;
* the full hierarchy: the torque, then the force, then u nearest u_pref (0), as levels.

Cold: no start. Warm: DAQP's primal start from its own answer to the tick before. Each answer
must agree with eqtrack's (the torque stage's achieved torque, the hierarchy's command) within
1e-6 of the largest bound. Prints a table of medians (DAQP's own solve_time; eqtrack's medians
measured in the same run) and their ratios; exits 1 when an answer differs.
"""
import csv
import json
import statistics
import sys

import daqp
import numpy as np


def nums(s):
    return np.array([float(x) for x in s.split()])


def problem(b, lo, hi, demand, levels, sw=None, up=None):
    """The hierarchical programme over x = [u, s (k), r (m)]: the bounds and the residual
    definitions s = B u - demand, r = sqrt(w) (u - up) hard, then `levels` (lists of residual
    indices: 0 to k-1 the wrench's, k and on r's) soft, in order. Default w = 1, up = 0.
    scripts/daqp/resolve.py poses each trajectory row with it too."""
    k, m = b.shape
    sw = np.ones(m) if sw is None else sw
    up = np.zeros(m) if up is None else up
    n = m + k + m
    rows, val, sense = [], [], []
    for i in range(k):
        r = np.zeros(n)
        r[:m], r[m + i] = -b[i], 1.0
        rows.append(r), val.append(-demand[i]), sense.append(5)
    for j in range(m):
        r = np.zeros(n)
        r[j], r[m + k + j] = -sw[j], 1.0
        rows.append(r), val.append(-sw[j] * up[j]), sense.append(5)
    breaks = [n + len(rows)]
    for level in levels:
        for i in level:
            r = np.zeros(n)
            r[m + i] = 1.0
            rows.append(r), val.append(0.0), sense.append(0)
        breaks.append(n + len(rows))
    big = 1e30
    bu = np.concatenate([hi, np.full(n - m, big), val])
    bl = np.concatenate([lo, np.full(n - m, -big), val])
    return (np.array(rows), bu, bl, np.array([0] * n + sense, dtype=np.int32),
            np.array(breaks, dtype=np.int32))


def solve(p, start=None):
    a, bu, bl, sense, breaks = p
    kw = {} if start is None else {"primal_start": start}
    x, _, flag, info = daqp.solve(None, None, a, bu, bl, sense, break_points=breaks, **kw)
    if flag < 0:
        raise RuntimeError(f"DAQP failed (exit flag {flag})")
    return x, info["solve_time"]


def main():
    eq = [json.loads(line) for line in open(sys.argv[2]) if line.strip()]
    times, worst = {}, 0.0
    last = {}
    with open(sys.argv[1], newline="") as f:
        for row in csv.DictReader(f):
            m = int(row["m"])
            b = nums(row["B"]).reshape(6, m)
            lo, hi, demand = nums(row["lo"]), nums(row["hi"]), nums(row["demand"])
            largest = max(np.abs(lo).max(), np.abs(hi).max())
            v, start = row["vehicle"], row["start"]
            first = problem(b, lo, hi, demand, [[0, 1, 2]])
            full = problem(b, lo, hi, demand, [[0, 1, 2], [3, 4, 5], list(range(6, 6 + m))])
            warm = last.get(v) if start == "warm" else None
            x1, t1 = solve(first, None if warm is None else warm[0])
            x3, t3 = solve(full, None if warm is None else warm[1])
            last[v] = (x1, x3)
            torque = b[:3] @ x1[:m] - b[:3] @ nums(row["u_first"])
            worst = max(worst, np.abs(torque).max() / largest, np.abs(x3[:m] - nums(row["u"])).max() / largest)
            times.setdefault((v, "first", start), []).append(t1 * 1e9)
            times.setdefault((v, "full", start), []).append(t3 * 1e9)
    print(f"{'vehicle':10} {'stage':6} {'start':5} {'DAQP median':>12} {'eqtrack median':>15} {'eqtrack/DAQP':>13}")
    for e in eq:
        key = (e["vehicle"], e["what"], e["start"])
        d = statistics.median(times[key])
        print(f"{key[0]:10} {key[1]:6} {key[2]:5} {d:10.0f} ns {e['median_ns']:13.0f} ns {e['median_ns'] / d:13.2f}")
    ok = worst <= 1e-6
    print(f"daqp: the answers {'agree' if ok else 'DIFFER'}: largest difference {worst:.1e} of the largest bound (limit 1e-6)")
    sys.exit(0 if ok else 1)


if __name__ == "__main__":
    main()
