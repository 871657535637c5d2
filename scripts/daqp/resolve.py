"""Re-solves every row's allocation of an eqtrack run with DAQP, a solver no one in this project
wrote, and checks eqtrack's answer against it and against the optimality conditions.

    python resolve.py SCENARIO.toml TRAJECTORY.csv [--perturb]

From the scenario's own table (parsed here, not by eqtrack): each actuator's effectiveness
column [p x a + c a ; a] (a normalised), its bounds, the failures the controller is told of,
the rate limit, [allocation] weights, preferred and priority. For each row of trajectory.csv,
from its demand_i (and the previous row's u_cmd_j, for the rate limit):

1. DAQP solves the prioritised problem as one hierarchical least-squares programme. DAQP
   normalises constraint rows, which would reweight a least-squares level, so every level is
   posed on residual variables: hard equalities s = B_tau u - tau, s_f = B_f u - f,
   r = sqrt(W) (u - u_pref), the bounds hard, then s = 0, s_f = 0 and r = 0 as soft levels in
   that order (each row a unit vector, which normalisation leaves alone).
2. |u_cmd - u_daqp| must be within 1e-6 of the largest bound.
3. The last stage's Karush-Kuhn-Tucker conditions at eqtrack's u_cmd, with the wrench it
   achieves held: W (u - u_pref) = B^T lam + mu_lo - mu_hi, mu >= 0 on held bounds, to 1e-6.

--perturb moves one u_cmd of the first row the active set solved by 1e-3 of the largest bound:
the comparison must then fail. Prints one summary line; exits 1 on a failure.
"""
import csv
import math
import sys
import tomllib

import daqp
import numpy as np

from bench import problem, solve


def vehicle(path):
    with open(path, "rb") as f:
        s = tomllib.load(f)
    v = s["vehicle"]
    group = s.get("group", "so3")
    k = 6 if group == "se3" else 3
    cols, lo, hi = [], [], []
    for a in v["actuator"]:
        # a planar (se2) thruster's (x, y) and in-plane axis, with z = 0
        p = np.array(list(a["position"]) + [0.0] * (3 - len(a["position"])), float)
        ax = np.array(list(a["axis"]) + [0.0] * (3 - len(a["axis"])), float)
        ax = ax / np.linalg.norm(ax)
        c = a.get("torque_per_thrust", 0.0)
        full = np.concatenate([np.cross(p, ax) + c * ax, ax])
        # se2's columns are (τ_z, f_x, f_y): rows 2, 3, 4 of the SE(3) column
        cols.append(full[2:5] if group == "se2" else full[:k])
        lo.append(a.get("min", 0.0))
        hi.append(a["max"])
    b = np.array(cols).T
    m = b.shape[1]
    alloc = s.get("allocation", {})
    w = np.array(alloc.get("weights", [1.0] * m), float)
    up = np.array(alloc.get("preferred", [0.0] * m), float)
    torque_first = alloc.get("priority", "torque") == "torque" and k == 6
    failures = [f for f in v.get("failure", []) if f.get("reconfigure", False)]
    rate = v.get("actuator_rate_limit", 0.0) * s["control_period"]
    return dict(b=b, lo=np.array(lo, float), hi=np.array(hi, float), w=w / w.max(), up=up,
                k=k, m=m, torque_first=torque_first, failures=failures, rate=rate,
                h=s["control_period"])


def bounds(veh, t, previous):
    lo, hi = veh["lo"].copy(), veh["hi"].copy()
    for f in veh["failures"]:
        if t >= f["t"] - veh["h"] / 2:
            # a told "stuck" actuator is held at its value, a "dead" one at 0
            if f.get("kind", "stuck") not in ("stuck", "dead"):
                sys.exit(f"resolve.py: a told {f['kind']!r} failure is not modelled here")
            lo[f["actuator"]] = hi[f["actuator"]] = f.get("value", 0.0)
    if veh["rate"] > 0 and previous is not None:
        for j in range(veh["m"]):
            if hi[j] > lo[j]:
                l = min(max(previous[j] - veh["rate"], lo[j]), hi[j])
                h = max(min(previous[j] + veh["rate"], hi[j]), l)
                lo[j], hi[j] = l, h
    return lo, hi


def daqp_solve(veh, demand, lo, hi):
    """The prioritised allocation as DAQP's hierarchical programme (bench.problem); (u,
    solve_time)."""
    k, m = veh["k"], veh["m"]
    groups = [[0, 1, 2], [3, 4, 5]] if veh["torque_first"] else [list(range(k))]
    p = problem(veh["b"], lo, hi, demand, groups + [list(range(k, k + m))],
                sw=np.sqrt(veh["w"]), up=np.clip(veh["up"], lo, hi))
    x, t = solve(p)
    return x[:m], t


def kkt(veh, u, lo, hi):
    """The least residual of the last stage's optimality conditions at u: W (u - u_pref) =
    B^T lam + sum mu_j (+e_j at a lower bound, -e_j at an upper one), mu >= 0 (either sign for a
    locked actuator), found as a bounded least-squares problem (by DAQP; the multipliers need
    not be unique)."""
    b, m = veh["b"], veh["m"]
    up = np.clip(veh["up"], lo, hi)
    grad = veh["w"] * (u - up)
    scale = 1.0 + np.abs(grad).max()
    tol = 1e-9 * (1.0 + max(np.abs(lo).max(), np.abs(hi).max()))
    cols, low = [b.T], [-1e30] * b.shape[0]
    for j in range(m):
        locked = hi[j] - lo[j] <= tol
        if u[j] <= lo[j] + tol or u[j] >= hi[j] - tol:
            sign = 1.0 if (locked or u[j] <= lo[j] + tol) else -1.0
            cols.append(sign * np.eye(m)[:, [j]])
            low.append(-1e30 if locked else 0.0)
    a = np.hstack(cols)
    nv = a.shape[1]
    h = a.T @ a + 1e-12 * np.eye(nv)
    y, _, flag, _ = daqp.solve(h, -a.T @ grad, np.zeros((0, nv)), np.full(nv, 1e30), np.array(low),
                               np.zeros(nv, dtype=np.int32))
    if flag < 0:
        raise RuntimeError(f"DAQP failed on the multipliers (exit flag {flag})")
    return np.abs(a @ y - grad).max() / scale


def main():
    scenario, trajectory = sys.argv[1], sys.argv[2]
    perturb = "--perturb" in sys.argv[3:]
    veh = vehicle(scenario)
    k, m = veh["k"], veh["m"]
    largest = max(np.abs(veh["lo"]).max(), np.abs(veh["hi"]).max())
    worst_u, worst_kkt, active, n, previous, planted = 0.0, 0.0, 0, 0, None, False
    with open(trajectory, newline="") as f:
        for r in csv.DictReader(f):
            t = float(r["t"])
            demand = np.array([float(r[f"demand_{i}"]) for i in range(k)])
            u = np.array([float(r[f"u_cmd_{j}"]) for j in range(m)])
            status = int(r["alloc_status"])
            lo, hi = bounds(veh, t, previous)
            previous = u.copy()
            if not all(math.isfinite(x) for x in demand):
                continue
            if perturb and not planted and status != 0:
                u[0] += 1e-3 * largest
                planted = True
            x, _ = daqp_solve(veh, demand, lo, hi)
            worst_u = max(worst_u, np.abs(x - u).max() / largest)
            worst_kkt = max(worst_kkt, kkt(veh, u, lo, hi))
            active += int(status != 0)
            n += 1
    ok = worst_u <= 1e-6 and worst_kkt <= 1e-6 and n > 0
    print(f"daqp: {scenario.split('/')[-1]}: {n} rows re-solved ({active} not met in full): "
          f"largest |u_cmd - u_daqp| {worst_u:.1e} of the largest bound, largest KKT violation {worst_kkt:.1e} "
          f"(limits 1e-6): {'agree' if ok else 'DIFFER'}")
    sys.exit(0 if ok else 1)


if __name__ == "__main__":
    main()
