"""HeartPole-v0 with heart_attack_proclivity=0, where drinking pays: a grid DP's policy, its score and a bound.

Run:
    python scripts/optimum_drinking.py policy [--rate 1.11] [--iterations 2] [--sweeps 300] [--episodes 2000]
    python scripts/optimum_drinking.py bound --rate 1.1235
    python scripts/optimum_drinking.py check [--decisions 300]
    (grid options for all three: --alertness-step 0.05 --fade-substeps 2)

policy: Dinkelbach's iteration through the evaluator: solve heartpole.optimum.solve_drinking at a rate, measure
its (stationary) policy's score over --episodes episodes of the standard evaluator, use that score as the next
rate. bound: solve the whole episode (max_steps sweeps, end-game included) at --rate and print the best
E[work - rate * time] from the episode's start; if it is negative, no policy reaches E[work] / E[time] >= rate
on the grid (time is at least max_steps). check: a fixed drinking rule's E[work] and E[time] on the grid against
the evaluator's episodes of the same rule (how the grid is checked against the env's dynamics).
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable

import numpy as np

KWARGS = {"heart_attack_proclivity": 0.0}


def check_rule(alertness: np.ndarray, intoxication: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Coffee below alertness 1.5, else beer below intoxication 0.125, else nothing; sleep after 45 half-hours."""
    action = np.where(alertness < 1.5, 1, np.where(intoxication < 0.125, 2, 0))
    return np.where(t >= 45, 3, action)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("what", choices=["policy", "bound", "check"])
    parser.add_argument("--rate", type=float, default=1.11, help="the (first) rate (default 1.11)")
    parser.add_argument("--sweeps", type=int, default=300, help="policy: value-iteration sweeps (default 300)")
    parser.add_argument("--iterations", type=int, default=2, help="policy: Dinkelbach iterations (default 2)")
    parser.add_argument("--episodes", type=int, default=2000, help="evaluation episodes (default 2000)")
    parser.add_argument("--decisions", type=int, default=300, help="check: decisions an episode (default 300)")
    parser.add_argument("--alertness-step", type=float, default=0.05, help="grid step (default 0.05)")
    parser.add_argument("--fade-substeps", type=int, default=2, help="intoxication points a fading (default 2)")
    args = parser.parse_args()
    grid = {"alertness_step": args.alertness_step, "fade_substeps": args.fade_substeps}
    label = f"alertness step {args.alertness_step}, {args.fade_substeps} fade substeps"
    {"policy": policy, "bound": bound, "check": check}[args.what](args, grid, label)


class Counted:
    """A policy that counts the actions it takes."""

    def __init__(self, policy: Callable[[np.ndarray], np.ndarray], actions: int) -> None:
        self.policy, self.counts = policy, np.zeros(actions)

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        actions = self.policy(obs)
        np.add.at(self.counts, actions, 1)
        return actions


def policy(args: argparse.Namespace, grid: dict[str, float], label: str) -> None:
    import heartpole
    from heartpole.optimum import solve_drinking
    from heartpole.registry import env_dynamics

    dynamics = env_dynamics("HeartPole-v0", KWARGS)
    rate = args.rate
    for _ in range(args.iterations):
        started = time.perf_counter()
        solution = solve_drinking(dynamics.params, rate, sweeps=args.sweeps, **grid)  # type: ignore[arg-type]
        seconds = time.perf_counter() - started
        counted = Counted(solution.policy(dynamics), len(dynamics.actions))
        result = heartpole.evaluate(counted, episodes=args.episodes, seed=0, env_kwargs=KWARGS)
        half = (result.score_ci95[1] - result.score_ci95[0]) / 2
        mix = ", ".join(f"{n / args.episodes:.0f} {a.name}" for n, a in zip(counted.counts, dynamics.actions))
        times = dynamics.params.max_steps + dynamics.params.sleep_half_hours * result.sleeps
        ratio = float((result.scores * times).mean() / times.mean())
        print(
            f"rate {rate:.4f}, {args.sweeps} sweeps, {label} ({seconds:.0f} s): "
            f"score {result.score:.4f} +- {half:.4f} (E[work] / E[time] {ratio:.5f}); an episode: {mix}",
            flush=True,
        )
        rate = result.score


def bound(args: argparse.Namespace, grid: dict[str, float], label: str) -> None:
    from heartpole.optimum import solve_drinking
    from heartpole.registry import env_dynamics

    params = env_dynamics("HeartPole-v0", KWARGS).params
    started = time.perf_counter()
    solution = solve_drinking(params, args.rate, sweeps=params.max_steps, **grid)  # type: ignore[arg-type]
    print(
        f"rate {args.rate:.4f}, {label} ({time.perf_counter() - started:.0f} s): the best E[work - rate * time] "
        f"over the episode is {solution.start_value:.3f}: on this grid no policy's E[work] / E[time] "
        + (f"reaches {args.rate:.4f}" if solution.start_value < 0 else f"exceeds {solution.rate_bound:.4f}"),
        flush=True,
    )


def check(args: argparse.Namespace, grid: dict[str, float], label: str) -> None:
    import heartpole
    from heartpole.optimum import drinking_rule_value
    from heartpole.registry import env_dynamics

    dynamics = env_dynamics("HeartPole-v0", KWARGS)
    work, spent = drinking_rule_value(dynamics.params, check_rule, args.decisions, **grid)
    indices = np.asarray([dynamics.action_index(n) for n in ("do_nothing", "drink_coffee", "drink_beer", "sleep")])
    kwargs = {**KWARGS, "max_steps": args.decisions}
    result = heartpole.evaluate(
        lambda obs: indices[check_rule(obs[:, 0], obs[:, 2], obs[:, 3])],
        episodes=args.episodes,
        seed=0,
        env_kwargs=kwargs,
    )
    times = args.decisions + dynamics.params.sleep_half_hours * result.sleeps
    works = result.scores * times
    half = 1.96 * works.std(ddof=1) / len(works) ** 0.5
    print(
        f"{args.decisions} decisions, {label}: the grid's E[work] {work:.2f}, E[time] {spent:.1f}; "
        f"the evaluator's E[work] {works.mean():.2f} +- {half:.2f}, E[time] {times.mean():.1f}",
        flush=True,
    )


if __name__ == "__main__":
    main()
