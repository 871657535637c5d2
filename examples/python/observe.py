#!/usr/bin/env python3
"""Watch a running eqtrack pair from Python, read-only.

    python3 -m venv .venv && .venv/bin/pip install iceoryx2==0.10.0   # matplotlib optional
    .venv/bin/python examples/python/observe.py --name RUN [--count N] [--plot FILE.png]

It attaches to the run's `state` and `command` blackboards (iceoryx2 shared memory) as a
reader. The plant and the controller do not notice it, and the services admit several
observers. It prints one line per new state: seq, t, the attitude error |Q - I| (or the pose's
rotation part), the torque of the command answering that state, and the Lyapunov value (and,
where the controller runs them, the disturbance estimate and the integral's torque; for a
vehicle, the allocator's status and the actuator commands). The
message layout is ipc_types/include/eqtrack_wire.h, documented in docs/wire.md.

It stops after --count states, when the plant ends the run, or after --timeout seconds.
With --plot FILE and matplotlib installed, it also draws the Lyapunov value and the torque.
Exit codes: 0 done, 1 no run found or nothing read.
"""
import argparse
import ctypes
import math
import sys
import time

import iceoryx2 as iox2

MAX_N, MAX_M, NAME_BYTES, SLOTS, MAX_ACTUATORS, MAX_WHEELS = 4, 6, 32, 8, 12, 6
SHUTDOWN = 2


class StateMsg(ctypes.Structure):
    """eqtrack::StateMsg7 (docs/wire.md)."""

    _fields_ = [
        ("version", ctypes.c_uint32),
        ("group", ctypes.c_uint32),
        ("seq", ctypes.c_uint64),
        ("t", ctypes.c_double),
        ("control_period", ctypes.c_double),
        ("stamp_ns", ctypes.c_uint64),
        ("q", ctypes.c_double * (MAX_N * MAX_N)),
        ("v", ctypes.c_double * MAX_M),
        ("applied", ctypes.c_double * MAX_M),
        ("flags", ctypes.c_uint32),
        ("plant_pid", ctypes.c_uint32),
        ("fingerprint", ctypes.c_uint64),
        ("scenario", ctypes.c_uint8 * NAME_BYTES),
        ("wheels", ctypes.c_uint32),
        ("reserved_wheels", ctypes.c_uint32),
        ("wheel_speeds", ctypes.c_double * MAX_WHEELS),
    ]

    @staticmethod
    def type_name():
        return "eqtrack::StateMsg7"


class CommandMsg(ctypes.Structure):
    """eqtrack::CommandMsg9 (docs/wire.md)."""

    _fields_ = [
        ("version", ctypes.c_uint32),
        ("group", ctypes.c_uint32),
        ("seq", ctypes.c_uint64),
        ("state_received_ns", ctypes.c_uint64),
        ("stamp_ns", ctypes.c_uint64),
        ("compute_ns", ctypes.c_uint64),
        ("tau", ctypes.c_double * MAX_M),
        ("lyapunov", ctypes.c_double),
        ("observer", ctypes.c_double * MAX_M),
        ("integral", ctypes.c_double * MAX_M),
        ("previous_seq", ctypes.c_uint64),
        ("estimate_before", ctypes.c_double * MAX_M),
        ("z_before", ctypes.c_double * MAX_M),
        ("heap_allocations", ctypes.c_uint64),
        ("flags", ctypes.c_uint32),
        ("mismatch", ctypes.c_uint32),
        ("fingerprint", ctypes.c_uint64),
        ("expected_period", ctypes.c_double),
        ("scenario", ctypes.c_uint8 * NAME_BYTES),
        ("law", ctypes.c_uint32),
        ("plans_received", ctypes.c_uint32),
        ("plan_seq", ctypes.c_uint64),
        ("plan_pid", ctypes.c_uint32),
        ("failsafe", ctypes.c_uint32),
        ("actuators", ctypes.c_uint32),
        ("alloc_status", ctypes.c_uint32),
        ("demand", ctypes.c_double * MAX_M),
        ("achieved", ctypes.c_double * MAX_M),
        ("accounted", ctypes.c_double * MAX_M),
        ("u_previous", ctypes.c_double * MAX_ACTUATORS),
        ("u_cmd", ctypes.c_double * MAX_ACTUATORS),
        ("detected", ctypes.c_uint32),
        ("detected_kind", ctypes.c_uint32),
        ("detected_value", ctypes.c_double),
        ("detected_refined", ctypes.c_uint32),
        ("alarms", ctypes.c_uint32),
        ("statistic", ctypes.c_double),
        ("suspect", ctypes.c_uint32),
        ("reserved_detector", ctypes.c_uint32),
    ]

    @staticmethod
    def type_name():
        return "eqtrack::CommandMsg9"


def entries(node, run, what, msg_type, timeout):
    """Read handles on every writer slot of `eqtrack/<run>/<what>` (waits for the service)."""
    name = iox2.ServiceName.new(f"eqtrack/{run}/{what}")
    until = time.monotonic() + timeout
    while True:
        try:
            service = (
                node.service_builder(name)
                .blackboard_opener(ctypes.c_uint32)
                .max_readers(6)
                .max_nodes(8)
                .open()
            )
            break
        except Exception as e:  # the run has not started yet
            if time.monotonic() > until:
                sys.exit(f"observe: no run `{run}` ({what}: {e})")
            time.sleep(0.05)
    reader = service.reader_builder().create()
    handles = [reader.entry(ctypes.c_uint32(k), msg_type) for k in range(SLOTS)]
    return service, reader, handles


def newest(handles, msg_type):
    """The most recently written message over all slots, or None."""
    best = None
    for h in handles:
        m = h.get().decode_as(msg_type)
        if m.version != 0 and (best is None or m.stamp_ns > best.stamp_ns):
            best = m
    return best


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--name", default="eqtrack", help="the run name (--name of the pair)")
    p.add_argument("--count", type=int, default=0, help="stop after this many states (0: run)")
    p.add_argument("--timeout", type=float, default=60.0, help="seconds to wait in all")
    p.add_argument("--plot", metavar="FILE", help="draw L and the torque (needs matplotlib)")
    a = p.parse_args()

    iox2.set_log_level_from_env_or(iox2.LogLevel.Error)
    node = iox2.NodeBuilder.new().create(iox2.ServiceType.Ipc)
    keep = [
        entries(node, a.name, "state", StateMsg, a.timeout),
        entries(node, a.name, "command", CommandMsg, a.timeout),
    ]
    states, commands = keep[0][2], keep[1][2]
    rows, last_seq = [], None
    until = time.monotonic() + a.timeout
    while time.monotonic() < until and (a.count == 0 or len(rows) < a.count):
        s = newest(states, StateMsg)
        if s is None or s.seq == last_seq:
            time.sleep(0.002)
            continue
        if s.flags & SHUTDOWN:
            print("observe: the plant ended the run")
            break
        last_seq = s.seq
        n, m = {1: (3, 3), 2: (4, 6), 3: (3, 3)}.get(s.group, (4, 6))
        err = math.sqrt(
            sum((s.q[i * n + j] - (1.0 if i == j else 0.0)) ** 2 for i in range(3) for j in range(3))
        )
        c = newest(commands, CommandMsg)
        answered = c is not None and c.seq == s.seq
        tau = [c.tau[i] for i in range(m)] if answered else [float("nan")] * m
        lyap = c.lyapunov if answered else float("nan")
        rows.append((s.seq, s.t, err, tau, lyap))
        # the disturbance-rejection terms, where the controller runs them
        terms = ""
        if answered and any(c.observer[i] != 0.0 or c.integral[i] != 0.0 for i in range(m)):
            terms = "  dhat " + " ".join(f"{c.observer[i]:+.4e}" for i in range(m))
            terms += "  integral " + " ".join(f"{c.integral[i]:+.4e}" for i in range(m))
        # a vehicle's actuator commands and the allocator's status
        if answered and 0 < c.actuators <= MAX_ACTUATORS:
            terms += f"  alloc {c.alloc_status}  u " + " ".join(
                f"{c.u_cmd[j]:+.4e}" for j in range(c.actuators)
            )
        print(
            f"seq {s.seq:8d}  t {s.t:9.4f} s  |Q-I| {err:.4e}  L {lyap:.5e}  tau "
            + " ".join(f"{x:+.4e}" for x in tau)
            + terms,
            flush=True,
        )
    if not rows:
        sys.exit("observe: no state read")
    print(f"observe: {len(rows)} states, seq {rows[0][0]} .. {rows[-1][0]}")
    if a.plot:
        try:
            import matplotlib

            matplotlib.use("Agg")
            import matplotlib.pyplot as plt
        except ImportError:
            print("observe: matplotlib is not installed; no plot")
            return
        fig, (ax1, ax2) = plt.subplots(2, 1, sharex=True)
        ts = [r[1] for r in rows]
        ax1.semilogy(ts, [r[4] for r in rows])
        ax1.set_ylabel("L")
        for i in range(len(rows[0][3])):
            ax2.plot(ts, [r[3][i] for r in rows], label=f"tau_{i}")
        ax2.set_xlabel("t (s)")
        ax2.legend()
        fig.savefig(a.plot)
        print(f"observe: wrote {a.plot}")


if __name__ == "__main__":
    main()
