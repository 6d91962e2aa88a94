"""Time to the first step: a fresh Python process that imports, makes HeartPole-v0, resets and steps once.

    python benchmarks/first_step.py                 # 5 repeats of each case
    python benchmarks/first_step.py --repeats 9 --out docs/results/first-step.txt
    python benchmarks/first_step.py --python /tmp/plain/bin/python   # another install's interpreter

The interpreter matters: in a venv with only HeartPole's own dependencies (``pip install heartpole``) a warm
start loads less than in one with the extras, where numba, loading compiled code, imports SciPy's BLAS
(about 0.5 s) because SciPy is there.

Three cases, each in fresh processes, the imports included, as a user waits for them:

* cold: numba finds an empty cache (a fresh ``NUMBA_CACHE_DIR``), so the step compiles: the first use
  after an install, and every use of a read-only install by a user with no writable home (where the step
  compiles in memory in every process);
* warm: the compiled step is loaded from the cache the cold run wrote;
* anchor: Gymnasium's CartPole-v1 in the same snippet, measured in the same run, pair by pair.

Each figure is the median and the range over the repeats, wall and CPU time (user + system) of the child:
on a shared machine the wall time counts other jobs too, the CPU time only this process. Goals (issue 23):
cold <= 5 s, warm <= 0.5 s on a 2-core machine. What a warm start spends is printed too (imports, make,
reset and step), from the process itself.
"""

from __future__ import annotations

import argparse
import os
import platform
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Sequence

SNIPPET = """\
import time
start = time.perf_counter()
import gymnasium as gym
{imports}
imported = time.perf_counter()
env = gym.make("{env_id}")
env.reset(seed=0)
reset = time.perf_counter()
env.step(1)
done = time.perf_counter()
print(f"{{imported - start:.3f}} {{reset - imported:.3f}} {{done - reset:.3f}}")
"""


def run(python: str, env_id: str, cache: str) -> tuple[float, float, list[float]]:
    """Wall and CPU seconds of one fresh process that steps ``env_id`` once, and its own split of the time."""
    imports = "import heartpole" if env_id.startswith("HeartPole") else ""
    code = SNIPPET.format(imports=imports, env_id=env_id)
    environment = {**os.environ, "NUMBA_CACHE_DIR": cache, "PYTHONWARNINGS": "ignore::DeprecationWarning"}
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    done = subprocess.run([python, "-c", code], env=environment, capture_output=True, text=True, check=True)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu, [float(x) for x in done.stdout.split()]


def summary(values: Sequence[float], unit: str = "s") -> str:
    """``median (min-max)``."""
    return f"{statistics.median(values):5.2f} {unit} ({min(values):.2f}-{max(values):.2f})"


def measure(repeats: int, python: str) -> list[str]:
    """The report's lines: cold, warm and the anchor, ``repeats`` times each, interleaved."""
    cases: dict[str, list[tuple[float, float, list[float]]]] = {"cold": [], "warm": [], "anchor": []}
    for _ in range(repeats):
        cache = tempfile.mkdtemp(prefix="heartpole-first-step-")
        try:
            cases["cold"].append(run(python, "HeartPole-v0", cache))
            cases["warm"].append(run(python, "HeartPole-v0", cache))
            cases["anchor"].append(run(python, "CartPole-v1", cache))
        finally:
            shutil.rmtree(cache, ignore_errors=True)
    goals = {"cold": "goal <= 5 s", "warm": "goal <= 0.5 s", "anchor": "Gymnasium's CartPole-v1"}
    packages = subprocess.run(
        [python, "-c", "import importlib.util as u; print(' '.join(n for n in ('scipy', 'torch') if u.find_spec(n)))"],
        capture_output=True, text=True, check=True,
    ).stdout.split()  # fmt: skip
    lines = [
        f"machine: {platform.machine()}, {os.cpu_count()} CPUs, CPython {platform.python_version()}; "
        f"{repeats} repeats, median (range)",
        f"interpreter: {'with the extras (' + ', '.join(packages) + ' installed)' if packages else 'a plain install'}",
        "time to the first step of HeartPole-v0 in a fresh process, imports included",
    ]
    for name, results in cases.items():
        walls, cpus = [r[0] for r in results], [r[1] for r in results]
        lines.append(f"  {name:<6} wall {summary(walls)}   CPU {summary(cpus)}   {goals[name]}")
    for name in ("cold", "warm"):
        ratios = [a[1] / b[1] for a, b in zip(cases[name], cases["anchor"])]
        lines.append(f"  {name} / anchor, CPU: {summary(ratios, 'x')}")
    split = [statistics.median(r[2][i] for r in cases["warm"]) for i in range(3)]
    lines.append(
        f"  warm, inside the process (medians): imports {split[0]:.2f} s, make and reset {split[1]:.2f} s "
        f"(numba loads the cached step), first step {split[2] * 1e3:.1f} ms"
    )
    return lines


def main(argv: Sequence[str] | None = None) -> None:
    """Measure and print (and with ``--out`` also write) the report."""
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeats", type=int, default=5, help="repeats of each case (default 5)")
    parser.add_argument("--out", help="also write the report to this file")
    parser.add_argument("--python", default=sys.executable, help="the interpreter to measure (default: this one)")
    args = parser.parse_args(argv)
    if args.repeats < 1:
        parser.error(f"--repeats must be >= 1, got {args.repeats}")
    report = "\n".join(measure(args.repeats, args.python)) + "\n"
    print(report, end="")
    if args.out:
        with open(args.out, "w") as file:
            file.write(report)


if __name__ == "__main__":
    main()
