#!/usr/bin/env python3
"""The seed paper's figure with matplotlib, from eqtrack.simulate: the Lyapunov function L,
the configuration error ||Q_E - I||_F and the momentum error ||p_E|| against time, for the
built-in seed scenario (the same numbers as `plant_sim sim --builtin seed`).

    python examples/python/seed_figure.py [--out seed.png]
"""

import argparse

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

import eqtrack  # noqa: E402


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", default="seed.png", help="the figure (PNG, or any format matplotlib writes)")
    a = p.parse_args()
    run = eqtrack.simulate(eqtrack.builtin_scenario("seed"))
    c = run.columns
    panels = [
        ("lyapunov", "Lyapunov function $L$", "$L$"),
        ("config_error", "Configuration error $\\|Q_E - I\\|_F$", "$\\|Q_E - I\\|_F$"),
        ("momentum_error", "Momentum error $\\|p_E\\|$", "$\\|p_E\\|$"),
    ]
    fig, axes = plt.subplots(len(panels), 1, figsize=(8, 8), sharex=True)
    for ax, (name, title, label) in zip(axes, panels):
        ax.plot(c["t"], c[name], color="tab:blue")
        ax.set_title(title)
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    axes[-1].set_xlabel("t (s)")
    s = run.summary
    fig.suptitle(f"{s['scenario']}: {s['law'].upper()} on {s['group'].upper()}, T = {s['duration']} s")
    fig.tight_layout()
    fig.savefig(a.out, dpi=100)
    print(f"L: {c['lyapunov'][0]:.4g} at t = 0, {s['final']['lyapunov']:.4g} at t = {s['duration']} s; wrote {a.out}")


if __name__ == "__main__":
    main()
