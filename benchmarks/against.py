"""``speed.py --against REV``: this tree's speed against another commit's, side by side in one run.

    python benchmarks/speed.py --against c32f124                # every measure, 5 rounds
    python benchmarks/speed.py --against c32f124 --rounds 7 --sizes 16384 --measures vector

REV is checked out as a git worktree in a temporary folder (removed at the end, on Ctrl-C and SIGTERM too).
Both trees are measured by this tree's ``speed.py --child`` in fresh Python processes, each importing its own
tree's sources (``PYTHONPATH=<tree>/src`` with this interpreter; numba caches its compiled loops beside each
tree's sources, and a warm-up process per tree fills that cache before any timing). Each measurement is a
ratio to its anchor measured in the same process, anchor-subject-anchor (the subject's rate over the
geometric mean of the two anchors', so that a load that rises or falls during the process cancels), timed
in the process's CPU time by default (``--clock wall`` for wall time: the same on a quiet machine; on a
shared one, CPU time leaves out the time the process waited for a core): the
single env against Gymnasium's ``CartPoleEnv``, the vector env against ``CartPoleVectorEnv``, the people's
vector env against the same tree's own v0. A round measures every measure once in each tree, the two trees
in turn (this tree first in even rounds, REV first in odd ones); the report gives each tree's ratios and the
ratio of the two, per round, as median and range over the rounds.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import json
import math
import os
import shutil
import signal
import statistics
import subprocess
import sys
import tempfile
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from types import FrameType
from typing import Any

HERE = Path(__file__).resolve().parent
TREE = HERE.parent
"""The tree this file belongs to: its sources are "this tree"."""

MEASURE_KINDS = ("single", "make", "vector", "people")
CLOCKS = ("cpu", "wall")  # speed.CLOCKS' names: speed.py imports this module, never the other way


@dataclass(frozen=True)
class Config:
    """What ``--against`` measures. Each field is also its command-line option (``--people-size`` for
    ``people_size``), with its default and help here."""

    against: str | None = field(default=None, metadata={"help": "compare with this commit (REV: a hash, tag, branch)"})
    rounds: int = field(default=5, metadata={"help": "rounds of alternating measurements (>= 1)"})
    measures: tuple[str, ...] = field(
        default=MEASURE_KINDS, metadata={"help": f"what to measure, any of {' '.join(MEASURE_KINDS)}"}
    )
    sizes: tuple[int, ...] = field(
        default=(256, 1024, 16384, 65536), metadata={"help": "the vector env's numbers of envs"}
    )
    people_size: int = field(default=16384, metadata={"help": "envs of the people='default' vector env"})
    single_steps: int = field(default=100_000, metadata={"help": "steps of a single env measurement"})
    env_steps: int = field(
        default=6_000_000, metadata={"help": "env-steps of a vector measurement (steps: this over the envs, 30-3000)"}
    )
    clock: str = field(
        default="cpu", metadata={"help": "time rates in the process's CPU time (cpu) or wall time (wall)"}
    )

    def __post_init__(self) -> None:
        for name in ("rounds", "people_size", "single_steps", "env_steps"):
            value = getattr(self, name)
            if type(value) is not int or value < 1:
                raise ValueError(f"--{_option(name)} must be an integer >= 1, got {value!r}")
        if not self.sizes or any(type(n) is not int or n < 1 for n in self.sizes):
            raise ValueError(f"--sizes must be integers >= 1, got {list(self.sizes)!r}")
        if self.clock not in CLOCKS:
            raise ValueError(f"--clock must be one of {' '.join(CLOCKS)}, got {self.clock!r}")
        unknown = [kind for kind in self.measures if kind not in MEASURE_KINDS]
        if unknown or not self.measures:
            raise ValueError(f"--measures must be some of {' '.join(MEASURE_KINDS)}, got {' '.join(self.measures)!r}")

    def command(self) -> str:
        """This configuration as the command that runs it, every option spelled out."""
        words = ["python", "benchmarks/speed.py"]
        for item in dataclasses.fields(self):
            value = getattr(self, item.name)
            words += [f"--{_option(item.name)}", *(map(str, value) if isinstance(value, tuple) else [str(value)])]
        return " ".join(words)

    def vector_steps(self, num_envs: int) -> int:
        """Steps of a vector measurement of ``num_envs`` envs."""
        return max(30, min(3000, self.env_steps // num_envs))

    def plan(self) -> list[Measure]:
        """The measures of a round, in order."""
        plan: list[Measure] = []
        if "single" in self.measures:
            plan.append(Measure("single env, unwrapped", "HeartPole-v0", "CartPole-v1", 0, self.single_steps))
        if "make" in self.measures:
            plan.append(Measure("single env, gym.make", "make:HeartPole-v0", "make:CartPole-v1", 0, self.single_steps))
        if "vector" in self.measures:
            for n in self.sizes:
                plan.append(
                    Measure(f"vector env, {n} envs", "HeartPoleVectorEnv", "CartPoleVectorEnv", n, self.vector_steps(n))
                )
        if "people" in self.measures:
            n = self.people_size
            people = "HeartPoleVectorEnv:people=default"
            plan.append(Measure(f"people='default', {n} envs", people, "HeartPoleVectorEnv", n, self.vector_steps(n)))
        return plan


def _option(name: str) -> str:
    return name.replace("_", "-")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """One option per [`Config`][] field, in a group of its own."""
    group = parser.add_argument_group("comparison with another commit (--against REV; see benchmarks/against.py)")
    for item in dataclasses.fields(Config):
        default = item.default
        extra: dict[str, Any] = {}
        if isinstance(default, tuple):
            extra = {"nargs": "+", "type": type(default[0]), "default": list(default)}
            if item.name == "measures":
                extra["choices"] = MEASURE_KINDS
        elif item.name == "clock":
            extra = {"type": str, "default": default, "choices": CLOCKS}
        else:
            extra = {"type": int if isinstance(default, int) else str, "default": default}
        metavar = "REV" if item.name == "against" else None
        group.add_argument(f"--{_option(item.name)}", metavar=metavar, help=item.metadata["help"], **extra)


def from_arguments(arguments: argparse.Namespace) -> Config:
    """The [`Config`][] of parsed command-line ``arguments``."""
    values = {}
    for item in dataclasses.fields(Config):
        value = getattr(arguments, item.name)
        values[item.name] = tuple(value) if isinstance(value, list) else value
    return Config(**values)


@dataclass(frozen=True)
class Measure:
    """One measurement of a round: ``subject``'s rate over ``anchor``'s (names of ``speed.py``'s env tables),
    a single env when ``num_envs`` is 0."""

    label: str
    subject: str
    anchor: str
    num_envs: int
    steps: int


@dataclass
class Tree:
    """A source tree measured: its label, its root and what its warm-up found."""

    label: str
    root: Path
    clock: str
    available: set[str] = field(default_factory=set)
    ratios: dict[str, list[float]] = field(default_factory=dict)
    rates: dict[str, list[float]] = field(default_factory=dict)

    def environment(self) -> dict[str, str]:
        """This interpreter's environment with the tree's sources first on the path."""
        return {**os.environ, "PYTHONPATH": str(self.root / "src")}

    def child(self, *arguments: str) -> Any:
        """Run ``speed.py --child ARGUMENTS`` (this tree's, beside this file) in a fresh process on the tree's
        sources; its JSON answer."""
        command = [sys.executable, str(HERE / "speed.py"), "--child", *arguments]
        done = subprocess.run(command, capture_output=True, text=True, env=self.environment())
        if done.returncode != 0:
            raise RuntimeError(f"{self.label}: {' '.join(arguments)} failed:\n{done.stderr[-3000:]}")
        return json.loads(done.stdout.strip().splitlines()[-1])

    def measure(self, measure: Measure) -> None:
        """One measurement in a fresh process, kept (nothing if the tree lacks its envs)."""
        if measure.subject not in self.available or measure.anchor not in self.available:
            return
        arguments = (measure.subject, measure.anchor, str(measure.num_envs), str(measure.steps), self.clock)
        answer = self.child("--pair", *arguments)
        ratio = answer["subject"] / math.sqrt(answer["anchors"][0] * answer["anchors"][1])
        self.ratios.setdefault(measure.label, []).append(ratio)
        self.rates.setdefault(measure.label, []).append(answer["subject"])


def git(*arguments: str) -> str:
    """``git`` in this tree's repository; its output, stripped."""
    return subprocess.run(
        ["git", "-C", str(TREE), *arguments], check=True, capture_output=True, text=True
    ).stdout.strip()


def resolve(rev: str) -> str:
    """The full hash of ``rev``, or ``SystemExit`` naming it."""
    done = subprocess.run(
        ["git", "-C", str(TREE), "rev-parse", "--verify", "--quiet", f"{rev}^{{commit}}"],
        capture_output=True,
        text=True,
    )
    if done.returncode != 0:
        raise SystemExit(f"--against: {rev!r} is not a commit of this repository (a hash, tag or branch is accepted)")
    return done.stdout.strip()


def _interrupt(signum: int, frame: FrameType | None) -> None:
    raise KeyboardInterrupt(f"signal {signum}")


@contextlib.contextmanager
def worktree(commit: str) -> Iterator[Path]:
    """A git worktree of ``commit`` in a temporary folder, removed when the block ends (an exception, Ctrl-C
    or SIGTERM included)."""
    folder = Path(tempfile.mkdtemp(prefix="heartpole-against-"))
    path = folder / "tree"
    previous = {number: signal.signal(number, _interrupt) for number in (signal.SIGINT, signal.SIGTERM)}
    try:
        git("worktree", "add", "--detach", "--quiet", str(path), commit)
        yield path
    finally:
        subprocess.run(["git", "-C", str(TREE), "worktree", "remove", "--force", str(path)], capture_output=True)
        shutil.rmtree(folder, ignore_errors=True)
        subprocess.run(["git", "-C", str(TREE), "worktree", "prune"], capture_output=True)
        for number, handler in previous.items():
            signal.signal(number, handler)


def compare(config: Config) -> None:
    """Measure this tree against ``config.against`` and print the report."""
    assert config.against is not None
    commit = resolve(config.against)
    head = git("rev-parse", "--short", "HEAD")
    dirty = " with uncommitted changes" if git("status", "--porcelain", "--untracked-files=no") else ""
    print(f"command: {config.command()}")
    print(f"this tree: {head}{dirty}; against: {config.against} = {commit[:12]}")
    try:
        plan, trees = measure_both(config, commit, head)
    except KeyboardInterrupt:
        raise SystemExit(f"interrupted: the worktree of {config.against} is removed") from None
    report(plan, trees)


def measure_both(config: Config, commit: str, head: str) -> tuple[list[Measure], list[Tree]]:
    """Every round of ``config`` in this tree and in a worktree of ``commit``: the plan and the trees measured."""
    with worktree(commit) as path:
        trees = [Tree(f"this tree ({head})", TREE, config.clock), Tree(config.against, path, config.clock)]
        plan = config.plan()
        print(_machine(trees[0]), flush=True)
        for tree in trees:
            names = sorted({name for m in plan for name in (m.subject, m.anchor)})
            found = tree.child("--warm-up", *names)
            if not Path(found["file"]).resolve().is_relative_to((tree.root / "src").resolve()):
                raise RuntimeError(f"{tree.label} imported heartpole from {found['file']}, not from its own tree")
            tree.available = set(found["available"])
            print(f"  {tree.label}: heartpole from {tree.root.name}/src, warm-up {found['seconds']:.1f} s", flush=True)
        for r in range(config.rounds):
            for measure in plan:
                for tree in trees if r % 2 == 0 else trees[::-1]:
                    tree.measure(measure)
            print(f"  round {r + 1} of {config.rounds} done", flush=True)
    return plan, trees


def _spread(values: Sequence[float], digits: int = 2, unit: str = "") -> str:
    if not values:
        return "n/a"
    return f"{statistics.median(values):.{digits}f}{unit} ({min(values):.{digits}f}-{max(values):.{digits}f})"


def report(plan: list[Measure], trees: list[Tree]) -> None:
    """The table: each tree's ratio to its anchor and the two trees' ratio, medians (ranges) over rounds."""
    this, other = trees
    print("\nratio to the anchor measured in the same process, median (range) over rounds;")
    print(f"'this/other': this tree's ratio over {other.label}'s, round by round\n")
    header = f"{'measure':<30} {'anchor':<19} {this.label:<20} {other.label:<20} {'this/other':<20} steps/s this, other"
    print(header)
    print("-" * len(header))
    for m in plan:
        a, b = this.ratios.get(m.label, []), other.ratios.get(m.label, [])
        quotient = [x / y for x, y in zip(a, b)]
        rates = ", ".join(f"{statistics.median(t.rates[m.label]):,.0f}" if m.label in t.rates else "n/a" for t in trees)
        anchor = m.anchor.replace("HeartPoleVectorEnv", "own v0")
        columns = (_spread(a, unit="x"), _spread(b, unit="x"), _spread(quotient, 3))
        print(f"{m.label:<30} {anchor:<19} " + " ".join(f"{c:<20}" for c in columns) + f" {rates}")


def _machine(tree: Tree) -> str:
    return tree.child("--machine")["machine"]  # type: ignore[no-any-return]
