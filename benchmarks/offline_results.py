"""The results table of docs/offline.md: standard datasets, OPE errors against the truth, offline learners.

Run (about 15 minutes on a busy 2-core machine; datasets go to a temporary Minari folder unless
MINARI_DATASETS_PATH is set)::

    python benchmarks/offline_results.py                 # rewrites the results section of docs/offline.md
    python benchmarks/offline_results.py --print-only    # prints it instead

For each dataset of the standard collection (``heartpole dataset --standard``) it reports the behaviour's
true return (expected-risk estimate, 95% interval), score and heart attacks; each OPE estimator's error
against the true discounted value of two target policies (``heartpole ope``); and the score, heart attacks
and return of behaviour cloning and discrete CQL trained on the dataset, evaluated with
``heartpole.evaluate`` (2,000 episodes).
"""

from __future__ import annotations

import argparse
import os
import re
import sys
import tempfile
import time
from pathlib import Path

import heartpole
from heartpole.offline.behaviour import EpsilonGreedy
from heartpole.offline.datasets import STANDARD_DATASETS, behaviour_policy, load_trajectories, record_standard
from heartpole.offline.learners import behaviour_cloning, conservative_q_learning
from heartpole.offline.ope import ESTIMATORS, estimate_all
from heartpole.offline.truth import true_value
from heartpole.policies import load_policy
from heartpole.reporting import plus_minus

DOC = Path(__file__).resolve().parent.parent / "docs" / "offline.md"
START, END = "<!-- offline-results:start -->", "<!-- offline-results:end -->"
GAMMA = 0.95
TARGETS = ("expert", "reference")
EPISODES = 1000
EVAL_EPISODES = 2000
SEED = 0


def behaviour_of(spec: heartpole.offline.datasets.DatasetSpec) -> EpsilonGreedy:
    """The behaviour policy a standard dataset is recorded with."""
    return behaviour_policy(spec.policy, spec.epsilon, seed=SEED)[1]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--print-only", action="store_true", help="print the section instead of writing the doc")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as folder:
        os.environ.setdefault("MINARI_DATASETS_PATH", folder)
        section = build()
    if args.print_only:
        print(section)
        return
    text = DOC.read_text()
    pattern = re.compile(re.escape(START) + ".*?" + re.escape(END), re.S)
    DOC.write_text(pattern.sub(lambda _: f"{START}\n{section}\n{END}", text))
    print(f"wrote the results section of {DOC}")


def build() -> str:
    started = time.perf_counter()
    record_started = time.perf_counter()
    ids = record_standard(EPISODES, seed=SEED, force=True)
    record_seconds = time.perf_counter() - record_started
    truths = {target: true_value(target, GAMMA, EVAL_EPISODES, seed=SEED) for target in TARGETS}
    datasets, ope, learners = [], [], []
    for spec, dataset_id in zip(STANDARD_DATASETS, ids):
        log(f"{dataset_id}: behaviour")
        behaviour = true_value(behaviour_of(spec), 1.0, EVAL_EPISODES, seed=SEED)
        datasets.append(
            [
                f"`{dataset_id}`",
                spec.description,
                plus_minus(behaviour.expected_return, behaviour.expected_return_ci95),
                f"{behaviour.score:.4f}",
                f"{behaviour.heart_attacks:.3f}",
            ]
        )
        data = load_trajectories(dataset_id)
        for target in TARGETS:
            log(f"{dataset_id}: OPE of {target}")
            truth = truths[target]
            for rewards in (False, True):
                estimates = {
                    e.estimator: e for e in estimate_all(data, load_policy(target), GAMMA, expected_rewards=rewards)
                }
                ope.append(
                    [
                        f"`{dataset_id.split('/')[-1]}`",
                        target,
                        "expected-risk" if rewards else "realized",
                        plus_minus(truth.value, truth.value_ci95),
                        *(f"{estimates[name].value - truth.value:+.3f}" for name in ESTIMATORS),
                    ]
                )
        for name, train in (
            ("BC", lambda d: behaviour_cloning(d, steps=3000, seed=SEED)),
            ("CQL (alpha=1)", lambda d: conservative_q_learning(d, alpha=1.0, steps=5000, seed=SEED)),
            ("CQL (alpha=0.1)", lambda d: conservative_q_learning(d, alpha=0.1, steps=5000, seed=SEED)),
        ):
            log(f"{dataset_id}: {name}")
            policy, _ = train(data)
            result = heartpole.evaluate(policy, episodes=EVAL_EPISODES, seed=SEED)
            learners.append(
                [
                    f"`{dataset_id.split('/')[-1]}`",
                    name,
                    f"{result.score:.4f}",
                    f"{result.heart_attacks_per_episode:.3f}",
                    plus_minus(result.expected_return, result.expected_ci95),
                    f"{result.drinks_per_episode:.1f}",
                    f"{result.sleeps_per_episode:.1f}",
                ]
            )
    minutes = (time.perf_counter() - started) / 60
    return "\n\n".join(
        [
            f"Generated by `python benchmarks/offline_results.py` ({minutes:.1f} min; the {len(ids)} datasets of "
            f"{EPISODES} episodes x 1,000 steps recorded and written in {record_seconds:.1f} s), heartpole "
            f"{heartpole.__version__}, seed {SEED}.",
            "**Standard datasets** (`heartpole dataset --standard`): the behaviour's true value over "
            f"{EVAL_EPISODES} episodes (undiscounted expected-risk return, 95% interval).",
            table(["dataset", "behaviour", "return (95% CI)", "score", "heart attacks / ep"], datasets),
            f"**Off-policy evaluation** (`heartpole ope --dataset ID --policy P [--expected-risk]`), gamma {GAMMA}: "
            "each estimator's error (estimate - truth) against the true discounted value from the start "
            f"state, measured over {EVAL_EPISODES} episodes.",
            table(["dataset", "target", "rewards", "true value (95% CI)", *ESTIMATORS], ope),
            "**Offline learners** trained on each dataset, evaluated with `heartpole.evaluate` "
            f"({EVAL_EPISODES} episodes; return is the expected-risk estimate with its 95% interval).",
            table(
                ["dataset", "learner", "score", "heart attacks / ep", "return (95% CI)", "drinks / ep", "sleeps / ep"],
                learners,
            ),
        ]
    )


def table(headers: list[str], rows: list[list[str]]) -> str:
    lines = ["| " + " | ".join(headers) + " |", "|" + "---|" * len(headers)]
    return "\n".join(lines + ["| " + " | ".join(row) + " |" for row in rows])


def log(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


if __name__ == "__main__":
    main()
