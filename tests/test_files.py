"""heartpole.files: files and folders written whole or not at all, and the signal policy of the command."""

from __future__ import annotations

import os
import signal
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from heartpole import files
from tests.signal_dispositions import as_in_a_terminal, pending

needs_signals = pytest.mark.skipif(not hasattr(signal, "SIGHUP"), reason="POSIX signals")
# The signals these tests raise do what they do in a terminal, however the run was started (nohup, a background job).
pytestmark = pytest.mark.usefixtures("terminal_signals")
FAILURES = [RuntimeError("boom"), KeyboardInterrupt(), SystemExit(1), files.Interrupted(signal.SIGINT)]


def tree(folder: Path) -> dict[str, bytes | None]:
    """Every path under ``folder`` (hidden ones too): a file's bytes, ``None`` for a folder."""
    return {str(p.relative_to(folder)): None if p.is_dir() else p.read_bytes() for p in sorted(folder.rglob("*"))}


@pytest.fixture
def umask_027() -> Iterator[None]:
    old = os.umask(0o027)
    yield
    os.umask(old)


# ------------------------------------------------------------------------------------------------------
# files


@pytest.mark.parametrize("failure", FAILURES, ids=lambda e: type(e).__name__)
def test_a_failed_write_leaves_nothing_and_keeps_the_old_files(tmp_path: Path, failure: BaseException) -> None:
    (tmp_path / "a.txt").write_text("old")
    before = tree(tmp_path)
    with (
        pytest.raises(type(failure)),
        files.atomic_files(tmp_path / "a.txt", tmp_path / "new" / "deep" / "b.csv") as (
            a,
            b,
        ),
    ):
        assert a.parent == tmp_path and a.name.startswith(".a.txt.") and a.suffix == ".txt"  # hidden, suffix kept
        assert b.parent == tmp_path / "new" / "deep" and b.suffix == ".csv"
        a.write_text("new")
        b.write_text("new")
        raise failure
    assert tree(tmp_path) == before  # no temporary file, no folder it made, the old file as it was


def test_files_are_moved_into_place_together_with_the_umasks_modes(tmp_path: Path, umask_027: None) -> None:
    targets = [tmp_path / "x" / "one.json", tmp_path / "two.txt"]
    with files.atomic_files(*targets) as temporaries:
        for temporary in temporaries:
            temporary.write_text("{}")
        assert not any(target.exists() for target in targets)  # nothing in place before the block ends
    assert [t.read_text() for t in targets] == ["{}", "{}"]
    assert sorted(os.listdir(tmp_path)) == ["two.txt", "x"] and os.listdir(tmp_path / "x") == ["one.json"]
    assert all(t.stat().st_mode & 0o777 == 0o640 for t in targets)  # not mkstemp's 0600
    assert (tmp_path / "x").stat().st_mode & 0o777 == 0o750


def test_write_json_and_text(tmp_path: Path) -> None:
    assert files.write_json(tmp_path / "a.json", {"x": [1, 2]}) == tmp_path / "a.json"
    assert (tmp_path / "a.json").read_text() == '{\n  "x": [\n    1,\n    2\n  ]\n}\n'
    with pytest.raises(ValueError):
        files.write_json(tmp_path / "a.json", {"x": float("nan")})
    assert "x" in (tmp_path / "a.json").read_text() and os.listdir(tmp_path) == ["a.json"]
    files.write_text(tmp_path / "a.json", "replaced")
    assert (tmp_path / "a.json").read_text() == "replaced"


# ------------------------------------------------------------------------------------------------------
# folders


def earlier(folder: Path) -> dict[str, bytes | None]:
    folder.mkdir(parents=True)
    (folder / "old.txt").write_text("old")
    (folder / "sub").mkdir()
    (folder / "sub" / "data.bin").write_bytes(b"\x00\x01")
    return tree(folder.parent)


@pytest.mark.parametrize("failure", FAILURES, ids=lambda e: type(e).__name__)
def test_a_failed_staged_folder_keeps_the_earlier_one(tmp_path: Path, failure: BaseException) -> None:
    before = earlier(tmp_path / "out")
    with pytest.raises(type(failure)), files.staged_folder(tmp_path / "out") as stage:
        assert stage.parent == tmp_path and stage.name.startswith(".out.") and stage.name.endswith(".partial")
        (stage / "new.txt").write_text("half")
        raise failure
    assert tree(tmp_path) == before
    with pytest.raises(type(failure)), files.staged_folder(tmp_path / "a" / "b" / "out") as stage:
        raise failure
    assert tree(tmp_path) == before  # the folders it made on the way are gone too


def test_a_staged_folder_replaces_the_earlier_one_when_done(tmp_path: Path, umask_027: None) -> None:
    earlier(tmp_path / "out")
    with files.staged_folder(tmp_path / "out") as stage:
        (stage / "new.txt").write_text("new")
    assert tree(tmp_path) == {"out": None, "out/new.txt": b"new"}
    assert (tmp_path / "out").stat().st_mode & 0o777 == 0o750  # not mkdtemp's 0700


def test_replace_folder_puts_the_earlier_one_back_if_the_move_fails(tmp_path: Path) -> None:
    before = earlier(tmp_path / "out")
    with pytest.raises(FileNotFoundError):
        files.replace_folder(tmp_path / "missing", tmp_path / "out")
    assert tree(tmp_path) == before


def test_a_folder_in_place_keeps_resumable_work_and_nothing_else(tmp_path: Path) -> None:
    target = tmp_path / "a" / "search"
    with pytest.raises(KeyboardInterrupt), files.folder_in_place(target, keep=lambda p: False) as folder:
        assert folder == target and target.is_dir()
        (target / "state.json").write_text("{}")
        raise KeyboardInterrupt
    assert tree(tmp_path) == {}  # nothing worth resuming: gone, with the folders it made
    with pytest.raises(KeyboardInterrupt), files.folder_in_place(target, keep=lambda p: True):
        (target / "state.json").write_text("{}")
        raise KeyboardInterrupt
    assert tree(tmp_path) == {"a": None, "a/search": None, "a/search/state.json": b"{}"}  # kept to resume
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(KeyboardInterrupt), files.folder_in_place(empty, keep=lambda p: False):
        (empty / "state.json").write_text("{}")
        raise KeyboardInterrupt
    assert empty.is_dir() and os.listdir(empty) == []  # there before, empty: left empty


@pytest.mark.parametrize("failure", FAILURES, ids=lambda e: type(e).__name__)
def test_a_folder_in_place_puts_the_earlier_folder_back(tmp_path: Path, failure: BaseException) -> None:
    before = earlier(tmp_path / "search")
    with pytest.raises(type(failure)), files.folder_in_place(tmp_path / "search", keep=lambda p: True) as folder:
        assert os.listdir(folder) == []  # the earlier folder is aside, hidden
        (folder / "state.json").write_text("{}")
        raise failure
    assert tree(tmp_path) == before
    with files.folder_in_place(tmp_path / "search", keep=lambda p: True) as folder:
        (folder / "state.json").write_text("{}")
    assert tree(tmp_path) == {"search": None, "search/state.json": b"{}"}  # done: the earlier one is deleted


# ------------------------------------------------------------------------------------------------------
# signals


@needs_signals
@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM, signal.SIGHUP])
def test_the_policy_raises_each_signal_and_restores_the_handlers(signum: int) -> None:
    before = {s: signal.getsignal(s) for s in files.SIGNALS}
    with pytest.raises(files.Interrupted) as raised, files.signal_policy():
        signal.raise_signal(signum)
    assert isinstance(raised.value, KeyboardInterrupt) and raised.value.signum == signum
    assert files.received_signal() == signum and files.exit_code() == 128 + signum
    assert {s: signal.getsignal(s) for s in files.SIGNALS} == before


@needs_signals
def test_an_ignored_signal_stays_ignored() -> None:
    previous = signal.signal(signal.SIGHUP, signal.SIG_IGN)
    try:
        with files.signal_policy():
            signal.raise_signal(signal.SIGHUP)  # nohup: nothing happens
            assert files.received_signal() is None and files.exit_code() == 130
    finally:
        signal.signal(signal.SIGHUP, previous)


@needs_signals
def test_signals_are_held_until_a_commit_is_done(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    replace = os.replace
    moved = []

    def replace_then_signal(source: str | os.PathLike[str], target: str | os.PathLike[str]) -> None:
        replace(source, target)
        moved.append(Path(target).name)
        signal.raise_signal(signal.SIGTERM)  # between the two moves: held until both are done

    monkeypatch.setattr(files.os, "replace", replace_then_signal)
    with pytest.raises(files.Interrupted), files.signal_policy():
        with files.atomic_files(tmp_path / "a", tmp_path / "b") as (a, b):
            a.write_text("a")
            b.write_text("b")
    assert moved == ["a", "b"] and sorted(os.listdir(tmp_path)) == ["a", "b"]
    assert files.exit_code() == 143


@needs_signals
def test_a_signal_while_cleaning_up_waits_for_the_cleanup(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    rmtree = files.shutil.rmtree

    def rmtree_signalled(path: str | os.PathLike[str], ignore_errors: bool = False) -> None:
        signal.raise_signal(signal.SIGHUP)  # a second signal as the staging folder is removed
        rmtree(path, ignore_errors=ignore_errors)

    monkeypatch.setattr(files.shutil, "rmtree", rmtree_signalled)
    before = earlier(tmp_path / "out")
    with pytest.raises(files.Interrupted) as raised, files.signal_policy():
        with files.staged_folder(tmp_path / "out") as stage:
            (stage / "half.txt").write_text("half")
            signal.raise_signal(signal.SIGTERM)
    assert tree(tmp_path) == before
    assert raised.value.signum == signal.SIGHUP and files.exit_code() == 143  # the first one counts


def test_held_signals_do_what_they_would_have_done_without_the_policy() -> None:
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
    done = []
    with pytest.raises(KeyboardInterrupt), files.signals_deferred():
        signal.raise_signal(signal.SIGINT)
        done.append(True)
    assert done == [True]


def test_signals_are_left_alone_outside_the_main_thread() -> None:
    seen: list[object] = []

    def work() -> None:
        with files.signal_policy(), files.signals_deferred(), files.signals_as_ctrl_c():
            seen.append(signal.getsignal(signal.SIGINT))

    thread = threading.Thread(target=work)
    thread.start()
    thread.join()
    assert seen == [signal.default_int_handler]


@needs_signals
def test_sigterm_and_sighup_stop_a_library_as_ctrl_c_would_once() -> None:
    stops: list[int] = []

    def graceful(signum: int, frame: object) -> None:  # as Ray Tune's: stop at the next step, keep going
        stops.append(signum)

    with files.signal_policy():
        policy = signal.getsignal(signal.SIGINT)
        with files.signals_as_ctrl_c():
            signal.signal(signal.SIGINT, graceful)  # installed by the library, never removed
            try:
                signal.raise_signal(signal.SIGTERM)
            except files.Interrupted:
                pytest.fail("SIGTERM raised at once, where Ctrl-C would let the library stop gracefully")
            assert stops == [signal.SIGINT] and files.received_signal() == signal.SIGTERM
            with pytest.raises(files.Interrupted):  # the second: at once
                signal.raise_signal(signal.SIGHUP)
        assert signal.getsignal(signal.SIGINT) is policy  # the library's handler is gone
    assert files.exit_code() == 143


@needs_signals
def test_a_signal_that_lands_where_python_ignores_exceptions_is_not_lost() -> None:
    class Finalized:
        def __del__(self) -> None:
            signal.raise_signal(signal.SIGTERM)  # the handler runs here, where a raise is only printed

    with pytest.raises(files.Interrupted) as raised, files.signal_policy():
        Finalized()
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline:  # the main thread's next steps
            time.sleep(0.001)
        pytest.fail("the signal was lost in __del__")
    assert raised.value.signum == signal.SIGTERM and files.exit_code() == 143


def test_a_library_error_raised_on_the_way_out_of_a_signal_still_exits_with_the_signal(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """A library whose cleanup fails as the Interrupted passes (torch's zip writer, cut mid-write, raises
    RuntimeError in its ``__exit__``) replaces the Interrupted: the command still exits with 128 + the signal."""
    import heartpole.cli as cli

    def cut_mid_write(argv: object, command: list[str]) -> int:
        try:
            os.kill(os.getpid(), signal.SIGTERM)
            time.sleep(5)
        finally:
            raise RuntimeError("unexpected pos 82990 vs 82960")  # noqa: B012 - what the library does
        return 0

    monkeypatch.setattr(cli, "_run", cut_mid_write)
    assert cli.main([]) == 128 + signal.SIGTERM
    assert "interrupted by SIGTERM" in capsys.readouterr().err


def test_a_library_error_without_a_signal_is_not_taken_for_one(monkeypatch: pytest.MonkeyPatch) -> None:
    import heartpole.cli as cli

    def fails(argv: object, command: list[str]) -> int:
        raise RuntimeError("a bug")

    monkeypatch.setattr(cli, "_run", fails)
    with pytest.raises(RuntimeError, match="a bug"):
        cli.main([])


def test_an_error_a_signal_caused_in_a_command_is_the_signals(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """A command's own error raised because a signal cut its work short (an import the signal broke: "plots
    need matplotlib") ends as the signal does, not as a usage error with exit code 2."""
    import argparse

    import heartpole.cli as cli
    from heartpole.cli.common import CommandError

    def plot(args: argparse.Namespace) -> int:
        try:
            os.kill(os.getpid(), signal.SIGTERM)
            time.sleep(5)
        except KeyboardInterrupt:
            raise CommandError("plots need matplotlib") from None
        return 0

    parser = argparse.ArgumentParser()
    parser.set_defaults(handler=plot, command="plot")
    monkeypatch.setattr(cli, "build_parser", lambda: parser)
    assert cli.main([]) == 128 + signal.SIGTERM
    err = capsys.readouterr().err
    assert "interrupted by SIGTERM" in err and "matplotlib" not in err


CUT_AN_EXTENSION = """
import _imp, os, signal, sys
from heartpole import files

cutting = []

def cut(frame, event, arg):  # SIGTERM at the first Python call of matplotlib.ft2font's C initialisation
    if event == "c_call" and arg is _imp.create_dynamic:
        cutting.append(getattr((frame.f_locals.get("args") or (None,))[0], "name", "") == "matplotlib.ft2font")
    elif event == "call" and any(cutting):
        sys.setprofile(None)
        os.kill(os.getpid(), signal.SIGTERM)

with files.signal_policy():
    try:
        sys.setprofile(cut)
        import matplotlib.ft2font
    except KeyboardInterrupt as interrupted:
        print("interrupted by", interrupted, "cut:", any(cutting))
    finally:
        sys.setprofile(None)
"""


@needs_signals
def test_a_signal_never_cuts_a_c_extensions_initialisation() -> None:
    """A signal while a C extension initialises (pybind11's call back into Python) waits until it is made:
    cut, matplotlib's ft2font failed with ``ImportError: initialization failed`` (``heartpole plot`` then said
    matplotlib was missing) and the interpreter aborted at exit. The signal still ends the import."""
    import subprocess
    import sys

    pytest.importorskip("matplotlib")
    result = subprocess.run([sys.executable, "-c", CUT_AN_EXTENSION], capture_output=True, text=True, timeout=120,
                            preexec_fn=as_in_a_terminal)  # fmt: skip
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == "interrupted by SIGTERM cut: True", result.stdout + result.stderr
    assert "Fatal Python error" not in result.stderr and "ImportError" not in result.stderr


ARRIVING_TOGETHER = """
import os
from heartpole import files, signals

policy_handler = signals._raise


def handler(signum, frame):  # the policy's, then which signal it takes for the first, on stdout
    try:
        policy_handler(signum, frame)
    finally:
        os.write(1, b"%d\\n" % files.received_signal())


signals._raise = handler
with files.signal_policy():
    print("ready", flush=True)
    while True:
        sum(range(10**9))  # one long C call: no handler runs in Python until it returns
"""


@pytest.mark.slow  # a child in a long C call: 3 s idle, 30 s and more on a busy machine
@needs_signals
def test_the_first_signal_to_arrive_decides_though_python_handles_sighup_first() -> None:
    """SIGTERM, SIGINT and SIGHUP, each handed to the process in turn while its main thread is in one long C call:
    Python then runs their handlers in the order of their numbers (SIGHUP first); the first signal is still SIGTERM,
    the first to arrive (`files` reads the order from its wakeup pipe); without the pipe it was SIGHUP."""
    import subprocess
    import sys

    child = subprocess.Popen([sys.executable, "-c", ARRIVING_TOGETHER], stdout=subprocess.PIPE, text=True,
                             preexec_fn=as_in_a_terminal)  # fmt: skip
    try:
        assert child.stdout is not None and child.stdout.readline() == "ready\n"
        time.sleep(0.2)  # into the C call
        for signum in (signal.SIGTERM, signal.SIGINT, signal.SIGHUP):
            child.send_signal(signum)
            deadline = time.monotonic() + 10
            while pending(child.pid) and time.monotonic() < deadline:  # handed over before the next is sent
                time.sleep(0.001)
        assert int(child.stdout.readline()) == signal.SIGTERM
    finally:
        child.kill()
        child.wait()


def test_an_output_announced_as_new_is_not_replaced_when_another_run_wrote_it_meanwhile(tmp_path: Path) -> None:
    from heartpole import paths

    first, second = tmp_path / "baselines.md", tmp_path / "baselines.csv"
    paths.forget_outputs()
    paths.expect_output(first, second, replace=False)  # a command without --force
    try:
        with pytest.raises(FileExistsError) as raised, files.atomic_files(first, second) as (a, b):
            a.write_text("ours")
            b.write_text("ours")
            second.write_text("theirs")  # another run placed its file while this one worked
        assert raised.value.filename == str(second) and "pass --force" in str(raised.value)
        assert not first.exists() and second.read_text() == "theirs"  # all or nothing; theirs kept
        assert sorted(p.name for p in tmp_path.iterdir()) == ["baselines.csv"]  # no temporary file left
        paths.forget_outputs()
        paths.expect_output(first, second)  # with --force
        with files.atomic_files(first, second) as (a, b):
            a.write_text("ours")
            b.write_text("ours")
        assert first.read_text() == second.read_text() == "ours"
    finally:
        paths.forget_outputs()
