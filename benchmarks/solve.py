"""Does `heartpole train` solve HeartPole-v0? The long benchmark behind the README's training table.

    python benchmarks/solve.py                    # default preset, seeds 0-4, then the tutorial preset
    python benchmarks/solve.py --seeds 0-9        # more seeds
    python benchmarks/solve.py --skip-tutorial    # only the default preset
    python benchmarks/solve.py --ablations        # also: each ingredient of the default removed, seed 0

Each run is exactly what `heartpole train --seed S --out DIR` does (training, saving, then 2,000
evaluation episodes of the saved model through `heartpole.evaluation`), timed from start to finish on
one PyTorch thread. The bar (issue 3): heart attacks <= 1.30 per episode and score >= 0.30, within 10
minutes of wall time, for at least 4 of 5 seeds. The machine is shared, so the script also measures an
anchor in the same run: the tutorial's DQN on `gym.make("HeartPole-v0")` for 20,000 steps (ANCHORS.md:
~1.5k steps/s), to compare wall times across machines by ratio.

Results land in --out (default runs/solve): one folder per run, and results.json / results.md with the
tables printed at the end.
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import torch

from heartpole import training
from heartpole.cli.train import parse_seeds
from heartpole.registry import quiet_version_warnings
from heartpole.training import ENV_REWARD, TrainConfig, TrainingReward, preset_config

WALL_LIMIT_S = 600.0


def ablations(timesteps: int | None) -> dict[str, TrainConfig]:
    """The default preset with one ingredient changed at a time (seed 0)."""
    base = preset_config("default") if timesteps is None else preset_config("default", timesteps=timesteps)
    shaped = base.reward
    hyper = dict(base.hyperparameters)
    return {
        "env reward (VecNormalize, tuned PPO)": replace(base, reward=ENV_REWARD, reward_stats_window=None),
        "realised heart attacks instead of their risk": replace(
            base, reward=TrainingReward(expected_risk=False, score_rate=shaped.score_rate, horizon=shaped.horizon)
        ),
        "telescoping score instead of the rate": replace(
            base, reward=TrainingReward(expected_risk=True, score_rate=None, horizon=shaped.horizon)
        ),
        "rate estimated while training (score_rate='auto')": replace(
            base, reward=TrainingReward(expected_risk=True, score_rate="auto", horizon=shaped.horizon)
        ),
        "discount 0.99 instead of 0.95": replace(base, hyperparameters={**hyper, "gamma": 0.99}),
        "no entropy bonus": replace(base, hyperparameters={**hyper, "ent_coef": 0.0}),
        "reward statistics over the whole run": replace(base, reward_stats_window=None),
        "A2C, default preset": preset_config("default", "a2c", timesteps=base.timesteps),
        "DQN, default preset": preset_config("default", "dqn", timesteps=base.timesteps),
        "PPO, tutorial preset (SB3 defaults, env reward)": preset_config("tutorial", "ppo", timesteps=base.timesteps),
    }


def anchor_steps_per_second(steps: int = 20_000) -> float:
    """The tutorial's DQN (net_arch [16, 16], SB3 defaults) on gym.make("HeartPole-v0"): steps per second."""
    from stable_baselines3 import DQN

    with quiet_version_warnings():
        env = gym.make("HeartPole-v0")
    model = DQN("MlpPolicy", env, policy_kwargs={"net_arch": [16, 16]}, seed=0, device="cpu")
    started = time.perf_counter()
    model.learn(total_timesteps=steps)
    return steps / (time.perf_counter() - started)


def run(name: str, config: TrainConfig, folder: Path, episodes: int) -> dict[str, Any]:
    """One training run as `heartpole train` does it; the summary with the name and configuration added."""
    print(
        f"\n== {name}: {config.algo} seed {config.seed}, {config.timesteps:,} steps, {config.n_envs} envs", flush=True
    )
    result = training.train_run(config, folder, eval_episodes=episodes, progress=True)
    result = {"name": name, "algo": config.algo, "preset": config.preset, "timesteps": config.timesteps, **result}
    result["within_limit"] = result["wall_seconds"] <= WALL_LIMIT_S
    print(
        f"   heart attacks {result['heart_attacks_per_episode']:.3f}, score {result['score']:.4f}, "
        f"return {result['mean_return']:.2f}, expected-risk return {result['expected_return']:.3f}, "
        f"{result['wall_seconds']:.0f} s: {'solved' if result['solved'] else 'not solved'}",
        flush=True,
    )
    return result


def markdown(rows: list[dict[str, Any]], first: str) -> str:
    """A README table of runs."""
    lines = [
        f"| {first} | heart attacks / episode | score | return [95% CI] | expected-risk return | wall time | solved |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        low, high = r["ci95"]
        label = r["seed"] if first == "seed" else r["name"]
        lines.append(
            f"| {label} | {r['heart_attacks_per_episode']:.3f} | {r['score']:.4f} | "
            f"{r['mean_return']:.1f} [{low:.1f}, {high:.1f}] | {r['expected_return']:.3f} | "
            f"{r['wall_seconds']:.0f} s | {'yes' if r['solved'] and r['within_limit'] else 'no'} |"
        )
    return "\n".join(lines)


def aggregate_line(rows: list[dict[str, Any]]) -> str:
    """The interquartile mean across seeds with its bootstrap interval, in one Markdown paragraph."""
    parts = [f"{label} {figure}" for label, figure in training.aggregate_figures(training.aggregate(rows))]
    solved = sum(r["solved"] and r["within_limit"] for r in rows)
    return (
        f"IQM across {len(rows)} seeds [95% bootstrap CI]: " + "; ".join(parts) + f". Solved: {solved} of {len(rows)}."
    )


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seeds", default="0-4", help="seeds of the default preset (default 0-4)")
    parser.add_argument("--timesteps", type=int, default=None, help="override the default preset's timesteps")
    parser.add_argument("--episodes", type=int, default=2000, help="evaluation episodes per run (default 2000)")
    parser.add_argument("--skip-tutorial", action="store_true", help="do not run the tutorial preset")
    parser.add_argument("--ablations", action="store_true", help="also run the ablations on seed 0")
    parser.add_argument("--out", default="runs/solve", help="output folder (default runs/solve)")
    parser.add_argument("--force", action="store_true", help="replace an earlier benchmark in --out")
    args = parser.parse_args()
    torch.set_num_threads(1)
    seeds = parse_seeds(args.seeds)
    out = Path(args.out)
    if out.exists() and any(out.iterdir()) and not args.force:
        print(f"solve.py: error: {out} exists and is not empty; pass --force", file=sys.stderr)
        return 2
    out.mkdir(parents=True, exist_ok=True)
    machine = (
        f"{platform.processor() or platform.machine()}, {torch.get_num_threads()} torch thread, "
        f"CPython {platform.python_version()}, torch {torch.__version__}"
    )
    print(f"machine: {machine}", flush=True)
    anchor = anchor_steps_per_second()
    print(f"anchor: tutorial DQN on gym.make('HeartPole-v0'): {anchor:,.0f} steps/s (ANCHORS.md: ~1.5k)", flush=True)

    base = preset_config("default") if args.timesteps is None else preset_config("default", timesteps=args.timesteps)
    default_rows = [
        run("default", replace(base, seed=seed), out / "default" / f"seed_{seed}", args.episodes) for seed in seeds
    ]
    tutorial_rows = []
    if not args.skip_tutorial:
        tutorial_rows.append(run("tutorial", preset_config("tutorial"), out / "tutorial" / "seed_0", args.episodes))
    ablation_rows = []
    if args.ablations:
        for index, (name, config) in enumerate(ablations(args.timesteps).items()):
            ablation_rows.append(run(name, config, out / "ablations" / f"{index}", args.episodes))

    report = [
        f"Machine: {machine}. Anchor measured in the same run: {anchor:,.0f} steps/s.",
        "",
        f"Default preset (`heartpole train --seed S`), {base.timesteps:,} steps:",
        "",
        markdown(default_rows, "seed"),
        "",
        aggregate_line(default_rows),
    ]
    if tutorial_rows:
        report += [
            "",
            "Tutorial preset (`heartpole train --preset tutorial`), seed 0:",
            "",
            markdown(tutorial_rows, "seed"),
        ]
    if ablation_rows:
        report += ["", "Ablations (seed 0):", "", markdown(ablation_rows, "run")]
    text = "\n".join(report)
    results = {
        "machine": machine,
        "anchor_steps_per_second": anchor,
        "default": default_rows,
        "aggregate": training.aggregate(default_rows),
        "tutorial": tutorial_rows,
        "ablations": ablation_rows,
        "numpy": np.__version__,
    }
    (out / "results.json").write_text(json.dumps(results, indent=2) + "\n")
    (out / "results.md").write_text(text + "\n")
    print("\n" + text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
