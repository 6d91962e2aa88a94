"""Every command that writes, ended by SIGINT, SIGTERM or SIGHUP mid-work, in a child process.

Each case runs ``python -m heartpole ...`` with small settings in a folder that already holds something
(often an earlier output that ``--force`` would replace), waits for a moment when the command is at work
(a staging folder or temporary file on disk, a progress bar on stderr), sends the signal and checks:

* the exit status is 128 + the signal's number (130, 143, 129);
* the folder holds exactly what it held before, byte for byte: no ``.partial`` folder, no temporary file,
  no new empty folder, the earlier output untouched;
* no process is left that names the folder (an ffmpeg still encoding), and nothing appears there later
  (a Ray worker writing after the command ended).

The default suite runs each case with one signal (the three signals spread over the cases) and signals at
the very start; ``-m slow`` runs every case with every signal, and the cases with Ray and JAX.
"""

from __future__ import annotations

import hashlib
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path

import pytest

from tests.signal_dispositions import as_in_a_terminal, ignoring, pending

pytestmark = pytest.mark.skipif(not hasattr(signal, "SIGHUP"), reason="POSIX signals")

SIGNALS = {"SIGINT": signal.SIGINT, "SIGTERM": signal.SIGTERM, "SIGHUP": getattr(signal, "SIGHUP", 1)}
START_TIMEOUT = 300  # seconds for a child to reach the moment of the signal (imports on a busy machine)
PROGRESS = {"HEARTPOLE_PROGRESS": "1"}  # progress bars on stderr: the sign that a command is at work
Ready = Callable[[Path, str], bool]  # (the work folder, the child's stdout and stderr so far) -> at work


def train(timesteps: int = 30000, eval_episodes: int = 200) -> list[str]:
    """``heartpole train`` with small settings (a few seconds of training)."""
    return ["train", "--timesteps", str(timesteps), "--n-envs", "2", "--eval-episodes", str(eval_episodes)]


def snapshot(folder: Path) -> dict[str, str]:
    """Every path under ``folder``, hidden ones included: a file's SHA-256, ``dir`` for a folder."""
    found = {}
    for path in sorted(folder.rglob("*")):
        relative = str(path.relative_to(folder))
        found[relative] = "dir" if path.is_dir() else hashlib.sha256(path.read_bytes()).hexdigest()
    return found


def processes_naming(text: str) -> list[str]:
    """Command lines of the live processes that mention ``text`` (an ffmpeg still writing there, say)."""
    found = []
    for entry in Path("/proc").iterdir() if Path("/proc").is_dir() else ():
        try:
            command = (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
        except OSError:
            continue
        if text in command and entry.name != str(os.getpid()):
            found.append(command)
    return found


@dataclass
class Case:
    """A command (``{work}`` stands for the folder it writes in), what that folder holds before it runs, and
    the sign that it is at work."""

    argv: list[str]
    ready: Ready
    before: Callable[[Path], None] = lambda work: None
    env: dict[str, str] = field(default_factory=dict)
    settle: float = 0.0  # seconds to watch the folder after the command ended (late writers)
    needs: str = "heartpole"  # a module the command needs (an optional extra)

    def command(self, work: Path) -> list[str]:
        return [sys.executable, "-m", "heartpole", *(a.replace("{work}", str(work)) for a in self.argv)]


def exists(pattern: str, *also: str) -> Ready:
    """Ready when a path matching ``pattern`` exists under the work folder (and the output shows ``also``)."""
    return lambda work, output: any(work.glob(pattern)) and all(text in output for text in also)


def says(text: str) -> Ready:
    """Ready when the child's output shows ``text``."""
    return lambda work, output: text in output


def earlier_run(work: Path) -> None:
    """An earlier training run in ``work/run`` (what ``--force`` may replace) and a file beside it."""
    (work / "run").mkdir()
    (work / "run" / "heartpole.json").write_text('{"earlier": true}\n')
    (work / "run" / "model.zip").write_bytes(os.urandom(4096))
    (work / "notes.txt").write_text("mine\n")


def earlier_figures(work: Path) -> None:
    from heartpole import plots

    (work / "figures").mkdir()
    for stem in plots.MODEL_FIGURES:
        (work / "figures" / f"{stem}.png").write_bytes(os.urandom(512))


def earlier_baselines(work: Path) -> None:
    (work / "results").mkdir()
    (work / "results" / "baselines.md").write_text("| earlier |\n")
    (work / "results" / "baselines.csv").write_text("earlier\n")


def earlier_dataset(work: Path) -> None:
    data = work / "minari" / "heartpole" / "v0" / "expert-eps10-v0" / "data"
    data.mkdir(parents=True)
    (data / "main_data.hdf5").write_bytes(os.urandom(2048))
    (data / "metadata.json").write_text('{"earlier": true}\n')


def earlier_optimum(work: Path) -> None:
    (work / "opt").mkdir()
    (work / "opt" / "optimum.json").write_text('{"earlier": true}\n')
    (work / "opt" / "optimum.npz").write_bytes(os.urandom(1024))


def earlier_search(work: Path) -> None:
    """An earlier search (what ``tune --force`` may replace)."""
    (work / "search" / "trials").mkdir(parents=True)
    (work / "search" / "search.json").write_text('{"earlier": true}\n')
    (work / "search" / "trials.csv").write_text("trial\n1\n")


def earlier_video(work: Path) -> None:
    (work / "episode.mp4").write_bytes(os.urandom(1024))


MINARI = {"MINARI_DATASETS_PATH": "{work}/minari"}
CASES: dict[str, Case] = {
    # train at four moments: before its output folder exists, while training, while evaluating, between seeds
    "train before its folder exists": Case([*train(), "--out", "{work}/new/run"], says("training PPO"), earlier_run),
    "train while training, --force": Case([*train(), "--force", "--out", "{work}/run"],
                                          exists(".run.*.partial", "training ppo seed"), earlier_run, PROGRESS),
    "train while evaluating": Case([*train(4000, eval_episodes=3000), "--out", "{work}/new/run"],
                                   exists("new/.run.*.partial/model.zip"), earlier_run),
    "train between seeds": Case([*train(5000), "--seeds", "0-1", "--force", "--out", "{work}/run"],
                                exists(".run.*.partial/seed_0/evaluation.json"), earlier_run),
    "dataset": Case(["dataset", "--policy", "expert", "--epsilon", "0.1", "--episodes", "3000", "--force"],
                    exists("minari/.heartpole-datasets.*.partial", "recording expert ["), earlier_dataset,
                    {**PROGRESS, **MINARI}),
    "dataset --standard": Case(["dataset", "--standard", "--episodes", "300", "--force"],
                               exists("minari/.heartpole-datasets.*.partial/heartpole/v0/reference-eps5-v0"),
                               earlier_dataset, MINARI),
    "record mp4": Case(["record", "--policy", "expert", "--force", "--out", "{work}/episode.mp4"],
                       exists(".episode.mp4.*.mp4", "recording episode.mp4 ["), earlier_video, PROGRESS),
    "record gif": Case(["record", "--policy", "expert", "--out", "{work}/new/episode.gif"],
                       exists("new/.episode.gif.*.gif", "recording episode.gif ["), earlier_video, PROGRESS),
    "plot model": Case(["plot", "model", "--force", "--out", "{work}/figures"], exists("figures/.*.png.*.png"),
                       earlier_figures),
    "plot episode": Case(["plot", "episode", "--policy", "expert", "--steps", "20000", "--out", "{work}/e/e.png"],
                         exists("e/.e.png.*.png")),
    "baselines": Case(["baselines", "--episodes", "2000", "--force", "--out", "{work}/results"],
                      says("reference ["), earlier_baselines, PROGRESS),
    "optimum --out": Case(["optimum", "--check", "3000", "--out", "{work}/opt"], says("checking expert ["),
                          earlier_optimum, PROGRESS),
    # Ray Tune trials in worker processes; PPO compiled with JAX (slow only: Ray starts in ~20 s, JAX compiles)
    "train --ray": Case([*train(5000), "--seeds", "0-1", "--ray", "--force", "--out", "{work}/run"],
                        exists(".run.*.partial/seed_*"), earlier_run, settle=5.0, needs="ray"),
    "train --backend jax, compiling": Case([*train(20000), "--backend", "jax", "--force", "--out", "{work}/run"],
                                           exists(".run.*.partial"), earlier_run, needs="jax"),
    "train --backend jax, training": Case([*train(50000), "--backend", "jax", "--force", "--out", "{work}/run"],
                                          says("compiled in"), earlier_run, needs="jax"),
    "tune --force": Case(["tune", "--trials", "2", "--seeds-per-trial", "1", *train(2048, 10)[1:], "--force",
                          "--out", "{work}/search"], exists("search/trials/*"), earlier_search, settle=5.0,
                         needs="ray"),
}  # fmt: skip

# The default suite: each case once, the three signals spread over them.
DEFAULT = {
    "train while training, --force": "SIGTERM",
    "train while evaluating": "SIGHUP",
    "dataset": "SIGINT",
    "record mp4": "SIGTERM",
    "plot model": "SIGHUP",
    "baselines": "SIGINT",
    "optimum --out": "SIGTERM",
}


# The slow stage: the other cases with every signal, but Ray's with one each (each run starts Ray: about 25 s). One
# handler serves the three signals (heartpole.signals); the cases above show it for each, Ray's the three between them
# (with test_an_interrupted_new_search_stays_only_to_resume).
RAY_ONLY = {"train --ray": "SIGINT", "tune --force": "SIGTERM"}


def matrix() -> list[object]:
    params = []
    for name in CASES:
        for signal_name in SIGNALS:
            if RAY_ONLY.get(name, signal_name) != signal_name:
                continue
            marks = [] if DEFAULT.get(name) == signal_name else [pytest.mark.slow]
            params.append(pytest.param(name, signal_name, marks=marks, id=f"{name}-{signal_name}"))
    return params


def prepare(case: Case, tmp_path: Path) -> dict[str, str]:
    """Make the work folder with what it holds before the command; its snapshot."""
    work = tmp_path / "work"
    work.mkdir()
    case.before(work)
    return snapshot(work)


def taken(process: subprocess.Popen[bytes]) -> None:
    """Wait until the kernel has handed ``process`` the signals sent to it, and 0.05 s more for its handler: signals
    that reach a process together are handed over lowest number first (SIGHUP before SIGINT before SIGTERM), so a
    burst sent to a process that does not run meanwhile (a busy machine) has no first signal to honour."""
    deadline = time.monotonic() + 30
    while pending(process.pid) and process.poll() is None and time.monotonic() < deadline:
        time.sleep(0.001)
    time.sleep(0.05 if Path("/proc").is_dir() else 0.5)


def run_and_signal(
    case: Case,
    signals: list[int],
    tmp_path: Path,
    gap: float = 0.0,
    allow_end: bool = False,
    preexec: Callable[[], None] = as_in_a_terminal,
) -> tuple[int, str]:
    """Run ``case`` in ``tmp_path/work`` (``preexec`` sets its signal dispositions: a terminal's); once it is at
    work, send ``signals``: the first, then, once it has taken it, the others ``gap`` seconds apart; return the exit
    status and stderr. Fails if it ended first, unless ``allow_end``."""
    work = tmp_path / "work"
    env = {**os.environ, **{k: v.replace("{work}", str(work)) for k, v in case.env.items()}}
    out, err = tmp_path / "stdout", tmp_path / "stderr"
    with out.open("w") as stdout, err.open("w") as stderr:
        process = subprocess.Popen(case.command(work), stdout=stdout, stderr=stderr, env=env, cwd=tmp_path,
                                   preexec_fn=preexec)  # fmt: skip
        try:
            deadline = time.monotonic() + START_TIMEOUT
            while process.poll() is None and time.monotonic() < deadline:
                if case.ready(work, out.read_text() + err.read_text()):
                    break
                time.sleep(0.005)
            assert allow_end or process.poll() is None, f"it ended before the moment to signal it:\n{err.read_text()}"
            assert time.monotonic() < deadline, f"it never reached the moment to signal it:\n{err.read_text()}"
            for n, signum in enumerate(signals if process.poll() is None else []):
                if n == 1:
                    taken(process)
                time.sleep(gap if n else 0.0)
                process.send_signal(signum)
            process.wait(timeout=120)
        finally:
            if process.poll() is None:
                process.kill()
                process.wait()
    return process.returncode, err.read_text()


def check_left_as_it_was(case: Case, tmp_path: Path, before: dict[str, str]) -> None:
    """The work folder as it was before, byte for byte; no process naming it; nothing written later."""
    work = tmp_path / "work"
    assert snapshot(work) == before
    assert processes_naming(str(work)) == []
    if case.settle:
        time.sleep(case.settle)
        assert snapshot(work) == before, "something was written after the command ended"


@pytest.mark.parametrize(("name", "signal_name"), matrix())
def test_a_signal_mid_work_leaves_the_folder_as_it_was(name: str, signal_name: str, tmp_path: Path) -> None:
    case, signum = CASES[name], SIGNALS[signal_name]
    pytest.importorskip(case.needs)
    before = prepare(case, tmp_path)
    code, err = run_and_signal(case, [signum], tmp_path)
    assert code == 128 + signum, err
    assert f"interrupted by {signal_name}" in err, err
    check_left_as_it_was(case, tmp_path, before)


@pytest.mark.parametrize("signal_name", SIGNALS)
def test_a_signal_as_the_command_starts_writes_nothing(signal_name: str, tmp_path: Path) -> None:
    """Sent as the child starts, before ``main`` installs the policy, Python's defaults apply (SIGTERM and
    SIGHUP end the process, SIGINT raises ``KeyboardInterrupt``, which ends the interpreter's own start-up with
    exit status 1); nothing has been written by then."""
    case, signum = CASES["plot model"], SIGNALS[signal_name]
    before = prepare(case, tmp_path)
    code, err = run_and_signal(replace(case, ready=lambda work, output: True), [signum], tmp_path)
    # Ctrl-C while Python itself starts (importing site) is a fatal error of the interpreter's start-up: exit 1
    in_startup = code == 1 and "init_import_site" in err and "KeyboardInterrupt" in err and signum == signal.SIGINT
    assert code in (-signum, 128 + signum) or in_startup, err
    check_left_as_it_was(case, tmp_path, before)


@pytest.mark.slow  # 15 runs: one signal (the handler is the same for the three, see `matrix`)
@pytest.mark.parametrize("signal_name", ["SIGTERM"])
def test_a_signal_at_any_moment_leaves_the_old_output_or_the_new(signal_name: str, tmp_path: Path) -> None:
    """``plot model --force`` signalled at moments spread over its whole run: it either finished (the new
    figures, all five) or left the earlier ones exactly as they were."""
    case, signum = CASES["plot model"], SIGNALS[signal_name]
    outcomes: set[tuple[int, bool]] = set()
    for n, delay in enumerate(0.4 * k for k in range(15)):
        run = tmp_path / str(n)
        run.mkdir()
        before = prepare(case, run)
        at = time.monotonic() + delay
        code, err = run_and_signal(replace(case, ready=lambda *_, at=at: time.monotonic() > at), [signum], run,
                                   allow_end=True)  # fmt: skip
        assert code in (0, -signum, 128 + signum), err
        after = snapshot(run / "work")
        new = sorted(after) == sorted(before) and all(after[k] != before[k] for k in after if k != "figures")
        assert new if code == 0 else after == before or new  # a late signal may come once all is written
        outcomes.add((code, new))
    assert (128 + signum, False) in outcomes, outcomes  # some moments fell while it was at work


def test_more_signals_while_it_cleans_up(tmp_path: Path) -> None:
    """A burst of signals (a second Ctrl-C, a process manager insisting): the first one's exit status, or the
    default end of the process for one that comes once the command is done; the folder as it was. The rest of the
    burst follows once the command has taken the first (see `taken`)."""
    case = CASES["train while training, --force"]
    before = prepare(case, tmp_path)
    burst = [signal.SIGTERM, signal.SIGTERM, signal.SIGINT, signal.SIGHUP, signal.SIGTERM, signal.SIGINT]
    code, err = run_and_signal(case, burst, tmp_path, gap=0.002)
    assert code in (143, -signal.SIGTERM, -signal.SIGINT, -signal.SIGHUP), err
    check_left_as_it_was(case, tmp_path, before)


@pytest.mark.parametrize("signal_name", ["SIGHUP", pytest.param("SIGINT", marks=pytest.mark.slow)])
def test_a_command_started_with_a_signal_ignored_keeps_ignoring_it(signal_name: str, tmp_path: Path) -> None:
    """``nohup`` starts a command with SIGHUP ignored, a background job of a non-interactive shell with SIGINT
    ignored: the command keeps ignoring it and writes its output whole (every figure new, nothing else there)."""
    case, signum = CASES["plot model"], SIGNALS[signal_name]
    before = prepare(case, tmp_path)
    code, err = run_and_signal(case, [signum, signum], tmp_path, gap=0.1, preexec=ignoring(signum), allow_end=True)
    assert code == 0, err
    assert "interrupted" not in err, err
    after = snapshot(tmp_path / "work")
    assert sorted(after) == sorted(before), "a figure missing, or a temporary file left"
    assert all(after[path] != before[path] for path in before if path != "figures"), "a figure not rewritten"
    assert processes_naming(str(tmp_path / "work")) == []


@pytest.mark.slow  # Ray starts each time: the signal Ray's cases of `matrix` leave out
@pytest.mark.parametrize("signal_name", ["SIGHUP"])
def test_an_interrupted_new_search_stays_only_to_resume(signal_name: str, tmp_path: Path) -> None:
    """A new search (no earlier one) stopped by a signal stays in --out if Ray Tune saved its state, and the
    command says how to resume it; otherwise nothing is left."""
    pytest.importorskip("ray")
    from heartpole import scale

    forced = CASES["tune --force"]
    case = replace(forced, argv=[a for a in forced.argv if a != "--force"], before=lambda work: None)
    signum = SIGNALS[signal_name]
    before = prepare(case, tmp_path)
    code, err = run_and_signal(case, [signum], tmp_path)
    assert code == 128 + signum, err
    work = tmp_path / "work"
    if "heartpole tune --resume --trust-pickles --out" in err:
        assert os.listdir(work) == ["search"] and scale.can_resume(work / "search")
    else:
        assert snapshot(work) == before
    assert processes_naming(str(work)) == []
