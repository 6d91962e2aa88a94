"""The per-seed table of one or more ``heartpole train --seeds`` runs, side by side, from their summary.json.

    python benchmarks/seeds_table.py docs/results/seeds-sb3-before.json docs/results/seeds-sb3.json \\
        --labels "3e-4 constant" "6e-4 annealed"

Each summary (what ``heartpole train --seeds 0-19 --out DIR`` writes to ``DIR/summary.json``) gives a column: a
seed's regret with its 95% interval, marked when it does not meet the solved bar (the interval's upper end at
most ``solved_bar.regret_at_most``). Below the table: seeds solved, the regrets' median and range, the
training time (SB3 trains seed after seed, so a seed's own time; JAX trains every seed in one compiled call, so
the call's) and the drinks per episode of the seeds' evaluations. Docs' tables of seeds are printed by this
script, not typed in.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
from pathlib import Path
from typing import Any


def load(path: Path) -> dict[str, Any]:
    """A summary.json, with a clear error naming the file where it is not one."""
    try:
        summary = json.loads(path.read_text())
        summary["runs"][0]["regret_ci95"]
    except (OSError, ValueError, KeyError, IndexError, TypeError) as error:
        what = "the summary.json of a `heartpole train --seeds` run"
        raise SystemExit(f"seeds_table.py: {path} is not {what} ({error})") from None
    return summary


def cell(run: dict[str, Any]) -> str:
    """A seed's regret with its interval, in bold where the seed is not solved."""
    low, high = run["regret_ci95"]
    text = f"{run['regret']:.4f} [{low:.4f}, {high:.4f}]"
    return text if run["solved"] else f"**{text}** (not solved)"


def training_time(summary: dict[str, Any]) -> str:
    """The training time in words: per seed (SB3) or for all seeds in one call (JAX)."""
    if "compile_seconds" in summary["runs"][0]:  # the JAX backend: every seed in one compiled call
        return f"{summary['runs'][0]['train_seconds']:.0f} s for all {len(summary['runs'])} seeds in one call"
    seconds = [run["train_seconds"] for run in summary["runs"]]
    return f"{statistics.median(seconds):.0f} s a seed (median; {min(seconds):.0f} to {max(seconds):.0f})"


def drinking(summary: dict[str, Any]) -> str:
    """The drinks per episode of the seeds' evaluations in words: none, or how many seeds drink and how much."""
    drinks = [run["drinks_per_episode"] for run in summary["runs"]]
    drinkers = sum(value > 0 for value in drinks)
    if not drinkers:
        return "no drinks in any seed's evaluation"
    return (f"{drinkers} of {len(drinks)} seeds drink, drinks per episode median {statistics.median(drinks):.3f}, "
            f"{min(drinks):.3f} to {max(drinks):.3f}")  # fmt: skip


def table(summaries: list[dict[str, Any]], labels: list[str]) -> str:
    """The Markdown table: a row per seed, a column per summary, then a line per summary."""
    runs = [{run["seed"]: run for run in summary["runs"]} for summary in summaries]
    seeds = sorted(set().union(*runs))
    lines = ["| seed | " + " | ".join(f"{label}: regret [95% CI]" for label in labels) + " |"]
    lines.append("|---" * (len(labels) + 1) + "|")
    for seed in seeds:
        lines.append(f"| {seed} | " + " | ".join(cell(r[seed]) if seed in r else "" for r in runs) + " |")
    lines.append("")
    for label, summary in zip(labels, summaries):
        regrets = [run["regret"] for run in summary["runs"]]
        solved = sum(run["solved"] for run in summary["runs"])
        bar = summary["runs"][0]["solved_bar"]["regret_at_most"]
        lines.append(
            f"- {label}: {solved} of {len(regrets)} seeds solved (upper end of the regret interval <= {bar}); "
            f"regret median {statistics.median(regrets):.4f}, {min(regrets):.4f} to {max(regrets):.4f}; "
            f"training {training_time(summary)}; {drinking(summary)}."
        )
    return "\n".join(lines)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("summaries", nargs="+", type=Path, help="summary.json files of `heartpole train --seeds`")
    parser.add_argument("--labels", nargs="+", help="a column title per summary (default: the files' names)")
    args = parser.parse_args()
    labels = args.labels or [path.stem for path in args.summaries]
    if len(labels) != len(args.summaries):
        parser.error(f"--labels needs one label per summary: {len(args.summaries)}, got {len(labels)}")
    print(table([load(path) for path in args.summaries], labels))
    return 0


if __name__ == "__main__":
    sys.exit(main())
