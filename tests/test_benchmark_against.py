"""benchmarks/against.py (``speed.py --against REV``): its configuration is its command line, a bad REV or
option is refused by name, the worktree of REV is gone when it ends, however it ends, and it runs speed.py in its
children without importing it (speed.py imports against.py, never the other way)."""

from __future__ import annotations

import argparse
import ast
import importlib.util
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
BENCHMARKS = ROOT / "benchmarks"


def load_against():
    spec = importlib.util.spec_from_file_location("against", BENCHMARKS / "against.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["against"] = module
    spec.loader.exec_module(module)
    return module


against = load_against()
in_git = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "HEAD"], capture_output=True).returncode == 0
needs_git = pytest.mark.skipif(not in_git, reason="needs the project's git repository")


def parse(words: list[str]):
    parser = argparse.ArgumentParser()
    against.add_arguments(parser)
    return against.from_arguments(parser.parse_args(words))


def test_the_configuration_is_its_command_line() -> None:
    config = against.Config(against="abc", rounds=3, measures=("vector", "people"), sizes=(64, 128), env_steps=999)
    command = config.command()
    assert command.startswith("python benchmarks/speed.py --against abc --rounds 3 --measures vector people")
    assert parse(command.split()[2:]) == config
    assert parse([]) == against.Config()  # every default is the option's
    assert [m.label for m in config.plan()] == [
        "vector env, 64 envs",
        "vector env, 128 envs",
        "people='default', 16384 envs",
    ]
    assert config.vector_steps(8) == 999 // 8 and config.vector_steps(1) == 999 and config.vector_steps(64) == 30
    assert against.Config().vector_steps(1) == 3000


@pytest.mark.parametrize(
    "words, match",
    [
        (["--rounds", "0"], "--rounds must be an integer >= 1, got 0"),
        (["--sizes", "0", "8"], r"--sizes must be integers >= 1, got \[0, 8\]"),
        (["--single-steps", "-5"], "--single-steps must be an integer >= 1, got -5"),
    ],
)
def test_bad_options_are_refused_by_name(words: list[str], match: str) -> None:
    with pytest.raises(ValueError, match=match):
        parse(words)


def test_a_clock_it_does_not_have_is_refused_by_name() -> None:
    with pytest.raises(ValueError, match="--clock must be one of cpu wall, got 'sundial'"):
        against.Config(clock="sundial")


def imported(path: Path) -> set[str]:
    """The top-level names of the modules ``path`` imports, wherever in the file."""
    names = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            names |= {alias.name.split(".")[0] for alias in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.add(node.module.split(".")[0])
    return names


def test_speed_imports_against_and_not_the_other_way() -> None:
    assert "against" in imported(BENCHMARKS / "speed.py")
    assert "speed" not in imported(BENCHMARKS / "against.py")


def test_a_child_answers_one_json_line_and_refuses_what_it_does_not_know() -> None:
    command = [sys.executable, str(BENCHMARKS / "speed.py"), "--child"]
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src")}
    done = subprocess.run([*command, "--machine"], capture_output=True, text=True, env=env, timeout=300, check=True)
    assert json.loads(done.stdout.strip().splitlines()[-1])["machine"].startswith("machine: ")
    refused = subprocess.run([*command, "--sundial"], capture_output=True, text=True, env=env, timeout=300)
    assert refused.returncode != 0 and "unknown child arguments ['--sundial']" in refused.stderr


@needs_git
def test_a_rev_that_is_no_commit_is_refused_by_name() -> None:
    with pytest.raises(SystemExit, match="--against: 'no-such-rev-xyz' is not a commit of this repository"):
        against.resolve("no-such-rev-xyz")
    assert against.resolve("HEAD") == against.git("rev-parse", "HEAD")


def worktrees() -> str:
    return against.git("worktree", "list", "--porcelain")


def comparison_worktrees() -> set[str]:
    """The worktrees comparisons made (the repository's others come and go with other work)."""
    return {line for line in worktrees().splitlines() if line.startswith("worktree ") and "heartpole-against-" in line}


@needs_git
def test_the_worktree_of_rev_holds_its_sources_and_is_removed_even_on_an_error() -> None:
    commit = against.resolve("HEAD")
    with pytest.raises(KeyboardInterrupt):
        with against.worktree(commit) as path:
            assert (path / "src" / "heartpole" / "env.py").is_file()
            assert str(path) in worktrees()
            raise KeyboardInterrupt  # as Ctrl-C or SIGTERM (whose handler raises it) would
    assert not path.parent.exists() and str(path) not in worktrees()


@pytest.mark.slow  # a fresh worktree compiles the loops (tens of seconds)
@needs_git
def test_a_comparison_runs_end_to_end_and_leaves_nothing_behind() -> None:
    before = comparison_worktrees()
    command = [sys.executable, str(BENCHMARKS / "speed.py"), "--against", "HEAD", "--rounds", "1"]
    command += ["--measures", "single", "--single-steps", "2000"]
    done = subprocess.run(command, capture_output=True, text=True, check=True, timeout=900)
    rows = [line for line in done.stdout.splitlines() if line.startswith("single env, unwrapped")]
    assert done.stdout.startswith("command: python benchmarks/speed.py --against HEAD --rounds 1 --measures single")
    assert len(rows) == 1 and "n/a" not in rows[0], done.stdout
    assert comparison_worktrees() <= before  # its own is gone (another comparison's may have ended meanwhile)
