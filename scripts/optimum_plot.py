"""The optimal sleep rule of HeartPole-v0: the alertness at which the optimum sleeps against the decisions left.

Run: python scripts/optimum_plot.py [--out docs/images/optimum.png]  (needs the plot extra: matplotlib)

Solves (or loads from the cache) HeartPole-v0's optimum with heartpole.optimum and draws its thresholds:
with n decisions left and t half-hours awake it sleeps when alertness < threshold[n, t]. One line per t
over the hours where days end (10-22 half-hours awake), against the expert's fixed threshold.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="docs/images/optimum.png", help="the PNG to write")
    args = parser.parse_args()

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from heartpole.model import productivity
    from heartpole.optimum import optimum
    from heartpole.parameters import Params
    from heartpole.policies import expert_rate

    solution = optimum("HeartPole-v0")
    alertness = np.linspace(0.0, 1.0, 100001)
    expert = alertness[np.argmax(productivity(alertness, 0.0) >= expert_rate(Params()))]
    n = np.arange(solution.params.max_steps + 1)
    thresholds = solution.thresholds_at(n)  # the rows end where the policy settles; later n use the last
    figure, axes = plt.subplots(1, 2, figsize=(12, 4.5), gridspec_kw={"width_ratios": [2, 1]})
    colors = plt.cm.viridis(np.linspace(0, 1, 13))
    for axis, (low, high) in zip(axes, [(1, 1000), (1, 120)]):
        for color, t in zip(colors, range(10, 23)):
            values = thresholds[low : high + 1, t]
            shown = np.where(np.isfinite(values), values, np.nan)
            axis.plot(n[low : high + 1], shown, ".", ms=2.5, color=color, label=f"t = {t}" if axis is axes[1] else None)
        axis.axhline(expert, color="crimson", lw=1, ls="--", label="expert" if axis is axes[1] else None)
        axis.set_xlim(high + (high - low) * 0.02, low - 1)
        axis.set_ylim(-0.3, 0.8)
        axis.set_xlabel("decisions left")
        axis.grid(alpha=0.3)
    axes[0].set_ylabel("sleeps when alertness falls below")
    axes[0].set_title("HeartPole-v0's optimum: the sleep threshold over the episode")
    axes[1].set_title("the end-game: the last 120 decisions")
    axes[1].legend(fontsize=7, ncol=2, title="half-hours awake", title_fontsize=7, loc="lower left")
    figure.tight_layout()
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    temporary = out.with_name(f".{out.name}.tmp.png")
    figure.savefig(temporary, dpi=110)
    temporary.replace(out)
    print(f"wrote {out}: expert sleeps below {expert:.3f}; optimum {solution.expected_return:.5f}")


if __name__ == "__main__":
    main()
