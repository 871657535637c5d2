"""Draws a run from its MCAP export with the Python packages `mcap` and `mcap-ros2-support`
(not from the project's CSV): the body velocity from /eqtrack/state, the torque and the
Lyapunov value from /eqtrack/command, and the plant's decision from /eqtrack/cycle.

    python plot_mcap.py RUN.mcap FIGURE.png      # needs matplotlib too

The figure of the seed run in docs/flight-recorder.md, "Looking at a run in Foxglove or PlotJuggler", is drawn with it.
"""

import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory


def main(path, figure):
    series = {"/eqtrack/state": [], "/eqtrack/command": [], "/eqtrack/cycle": []}
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        meta = {m.name: dict(m.metadata) for m in reader.iter_metadata()}.get("eqtrack", {})
        for _, channel, message, decoded in reader.iter_decoded_messages(topics=list(series)):
            series[channel.topic].append((message.log_time / 1e9, decoded))
    fig, axes = plt.subplots(4, 1, figsize=(9, 10), sharex=True)
    t = [s[0] for s in series["/eqtrack/state"]]
    for i in range(3):
        axes[0].plot(t, [s[1].v[i] for s in series["/eqtrack/state"]], label=f"v[{i}]")
    axes[0].set_ylabel("body velocity (rad/s)")
    axes[0].set_title("/eqtrack/state: v")
    t = [s[0] for s in series["/eqtrack/command"]]
    for i in range(3):
        axes[1].plot(t, [s[1].tau[i] for s in series["/eqtrack/command"]], label=f"tau[{i}]")
    axes[1].set_ylabel("torque (N m)")
    axes[1].set_title("/eqtrack/command: tau")
    axes[2].semilogy(t, [s[1].lyapunov for s in series["/eqtrack/command"]])
    axes[2].set_ylabel("L")
    axes[2].set_title("/eqtrack/command: lyapunov")
    t = [s[0] for s in series["/eqtrack/cycle"]]
    axes[3].plot(t, [s[1].decision for s in series["/eqtrack/cycle"]], drawstyle="steps-post")
    axes[3].set_yticks([0, 1, 2], ["fresh", "held", "safe mode"])
    axes[3].set_title("/eqtrack/cycle: decision")
    axes[3].set_xlabel("t (s)")
    for ax in axes[:2]:
        ax.legend(loc="upper right")
    fig.suptitle(
        f"{meta.get('scenario', '?')} ({meta.get('law', '?')} on {meta.get('group', '?')}, {meta.get('mode', '?')}), "
        f"read from {path.split('/')[-1]} with mcap + mcap-ros2-support"
    )
    fig.tight_layout()
    fig.savefig(figure, dpi=90)


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
