"""HeartPole-v0 with heart_attack_proclivity=0, where drinking pays: a grid DP's policy and its score.

Run: python scripts/optimum_drinking.py [--sweeps 300] [--iterations 2] [--episodes 2000]

Dinkelbach's iteration through the evaluator: solve heartpole.optimum.solve_drinking at a rate, measure
its policy's score over --episodes episodes of the standard evaluator, use that score as the next rate.
Each solve takes about 4 minutes on a busy 2-core machine (300 sweeps of a 281 x 151 x 90 grid).
"""

from __future__ import annotations

import argparse
import time


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rate", type=float, default=1.1, help="the first rate (default 1.1)")
    parser.add_argument("--sweeps", type=int, default=300, help="value-iteration sweeps (default 300)")
    parser.add_argument("--iterations", type=int, default=2, help="Dinkelbach iterations (default 2)")
    parser.add_argument("--episodes", type=int, default=2000, help="evaluation episodes (default 2000)")
    parser.add_argument("--alertness-step", type=float, default=0.025, help="grid step (default 0.025)")
    parser.add_argument("--intoxication-step", type=float, default=0.002, help="grid step (default 0.002)")
    args = parser.parse_args()

    import heartpole
    from heartpole.optimum import solve_drinking
    from heartpole.policies import env_dynamics

    kwargs = {"heart_attack_proclivity": 0.0}
    dynamics = env_dynamics("HeartPole-v0", kwargs)
    rate = args.rate
    for _ in range(args.iterations):
        started = time.perf_counter()
        solution = solve_drinking(
            dynamics.params,
            rate,
            sweeps=args.sweeps,
            alertness_step=args.alertness_step,
            intoxication_step=args.intoxication_step,
        )
        seconds = time.perf_counter() - started
        result = heartpole.evaluate(solution.policy(dynamics), episodes=args.episodes, seed=0, env_kwargs=kwargs)
        half = (result.score_ci95[1] - result.score_ci95[0]) / 2
        print(
            f"rate {rate:.4f}, {args.sweeps} sweeps, steps {args.alertness_step} x {args.intoxication_step} "
            f"({seconds:.0f} s): score {result.score:.4f} +- {half:.4f}, "
            f"{result.drinks_per_episode:.0f} drinks and {result.sleeps_per_episode:.1f} sleeps an episode",
            flush=True,
        )
        rate = result.score


if __name__ == "__main__":
    main()
