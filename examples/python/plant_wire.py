"""A plant process's side of the wire, in Python (docs/wire.md): the run's state and command
blackboards and the state event, opened with iceoryx2's own Python bindings. The MuJoCo and
Basilisk plants (examples/mujoco/, examples/basilisk/) publish their states through it and wait
for the unchanged controller_node's commands, in lockstep.
"""
import ctypes
import os
import sys
import time

import iceoryx2 as iox2

from observe import SLOTS, CommandMsg, StateMsg

PROTOCOL, SO3, SE3, SHUTDOWN = 10, 1, 2, 2


def fail(who, code, msg):
    """Prints `who: msg` to stderr and exits with `code`."""
    print(f"{who}: {msg}", file=sys.stderr)
    sys.exit(code)


def board(node, run, what, msg_type, who):
    """Opens the run's board `what`, or creates it with empty slots (the same settings as
    link's: 8 slots, 6 readers, 8 nodes)."""
    name = iox2.ServiceName.new(f"eqtrack/{run}/{what}")
    until = time.monotonic() + 10.0
    while True:
        try:
            return (
                node.service_builder(name)
                .blackboard_opener(ctypes.c_uint32)
                .max_readers(6)
                .max_nodes(8)
                .open()
            )
        except Exception:
            pass
        try:
            creator = node.service_builder(name).blackboard_creator(ctypes.c_uint32)
            creator = creator.max_readers(6).max_nodes(8)
            for k in range(SLOTS):
                creator = creator.add(ctypes.c_uint32(k), msg_type())
            return creator.create()
        except Exception as e:
            if time.monotonic() > until:
                fail(who, 1, f"cannot open or create eqtrack/{run}/{what}: {e}")
            time.sleep(0.01)


class Wire:
    """The plant's side of run `run` on group `group` (SO3 or SE3): the state board's first
    free slot, the command board's slots, and the state event that wakes the controller."""

    def __init__(self, node, run, group, who):
        self.group, self.who = group, who
        state = board(node, run, "state", StateMsg, who)
        command = board(node, run, "command", CommandMsg, who)
        event = (
            node.service_builder(iox2.ServiceName.new(f"eqtrack/{run}/state_event"))
            .event()
            .max_notifiers(2)
            .max_listeners(2)
            .max_nodes(8)
            .open_or_create()
        )
        self.notifier = event.notifier_builder().create()
        self.writer = state.writer_builder().create()
        self.out = None
        for k in range(SLOTS):
            try:
                self.out = self.writer.entry(ctypes.c_uint32(k), StateMsg)
                break
            except Exception:
                continue
        if self.out is None:
            fail(who, 1, f"every writer slot of eqtrack/{run}/state is taken")
        self.reader = command.reader_builder().create()
        self.slots = [self.reader.entry(ctypes.c_uint32(k), CommandMsg) for k in range(SLOTS)]
        self._keep = (state, command, event)

    def publish(self, msg):
        msg.stamp_ns = time.monotonic_ns()
        self.out.update_with_copy(msg)
        self.notifier.notify()

    def command(self, seq, timeout):
        """The controller's command for state `seq`, waited for (polled) up to `timeout` s."""
        until = time.monotonic() + timeout
        while time.monotonic() < until:
            for h in self.slots:
                c = h.get().decode_as(CommandMsg)
                if c.version == PROTOCOL and c.seq == seq and c.group == self.group:
                    if c.flags & 4:
                        fail(self.who, 1, f"the controller refused the run (mismatch bits {c.mismatch})")
                    return c
            time.sleep(20e-6)
        fail(self.who, 1, f"no command for state {seq} within {timeout} s")

    def exchange(self, k, h, q, v, applied, count, wheel_speeds=()):
        """One lockstep period: state `k` out (the configuration `q` row-major, the body velocity
        `v`, the wrench `applied` over the last period, the wheels' speeds), the controller's
        command for it in (waited for 30 s for the first state, 10 s after). Exits 1 unless it
        commands `count` actuators. Returns the command, its first `count` actuator commands and
        the wrench it accounts for."""
        m = 6 if self.group == SE3 else 3
        msg = StateMsg(version=PROTOCOL, group=self.group, seq=k, t=k * h, control_period=h)
        msg.q[: len(q)] = list(q)
        msg.v[:m] = list(v)
        msg.applied[:m] = list(applied)
        msg.wheels = len(wheel_speeds)
        msg.wheel_speeds[: len(wheel_speeds)] = list(wheel_speeds)
        msg.plant_pid = os.getpid()
        self.publish(msg)
        c = self.command(k, 30.0 if k == 0 else 10.0)
        if c.actuators != count:
            fail(self.who, 1, f"the controller sends {c.actuators} actuator commands, the plant has {count}")
        return c, [c.u_cmd[j] for j in range(count)], [c.accounted[i] for i in range(m)]

    def bye(self, seq, h):
        """The state after the last: the run is over (the controller exits)."""
        msg = StateMsg(version=PROTOCOL, group=self.group, seq=seq, t=seq * h, control_period=h)
        msg.flags = SHUTDOWN
        msg.plant_pid = os.getpid()
        self.publish(msg)
