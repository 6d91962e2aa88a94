"""The optimum at the settings where drinking was refused before the lifetime check (issue 42): a markdown table.

    python benchmarks/drinking_settings.py [--settings heart_attack_penalty=30 ...]

Each row is `heartpole.optimum.frontier_point` of one setting of v0 (solved once, then cached): its interval on
the optimum's return, its width against the return, and what the policy drinks. A setting where a drink pays is
shown as refused, with the reason's first words.
"""

from __future__ import annotations

import argparse
import math
import time

from heartpole.optimum import NotCoveredError, frontier_point, optimum

SETTINGS = (
    "heart_attack_penalty=50",
    "heart_attack_penalty=30",
    "heart_attack_penalty=10",
    "heart_attack_proclivity=0.2",
    "heart_attack_penalty=1",
    "heart_attack_penalty=0",
)


def row(setting: str) -> str:
    """One markdown row for ``name=value``."""
    name, value = setting.split("=")
    kwargs = {name: float(value)}
    begun = time.perf_counter()
    try:
        optimum("HeartPole-v0", kwargs)  # refuses where a drink may pay, without solving the coffee program
    except NotCoveredError as refused:
        return f"| {setting} | refused: {str(refused)[:90]}... | | | | | {time.perf_counter() - begun:.0f} |"
    point = frontier_point("HeartPole-v0", **kwargs)
    width = point.upper - point.lower
    relative = width / abs(point.expected_return) if point.expected_return else math.inf
    return (
        f"| {setting} | {point.lower:.6f} | {point.upper:.6f} | {width:.1e} ({relative:.1e} of the return) | "
        f"{point.drinks_per_episode:g} ({point.coffees_per_episode:g} coffees, {point.beers_per_episode:g} beers) | "
        f"{point.expected_attacks:.5f} | {time.perf_counter() - begun:.0f} |"
    )


def main() -> None:
    """Print the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--settings", nargs="+", default=list(SETTINGS), help="name=value settings of v0")
    args = parser.parse_args()
    print("| setting | lower | upper | width | drinks / episode | attacks / episode | s (this process) |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    for setting in args.settings:
        print(row(setting), flush=True)


if __name__ == "__main__":
    main()
