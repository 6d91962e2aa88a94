"""The ``heartpole`` command: one entry point, one subcommand per module of this package.

Each module here that defines ``register(subparsers)`` adds its subcommands; a subcommand's handler
takes the parsed arguments and returns an exit code. The command line only parses, calls the library
and prints: the logic lives in the modules below it. Errors a user can cause (bad arguments, missing
files) end in one clear line on stderr and exit code 2, never a traceback.
"""

from __future__ import annotations

import argparse
import atexit
import errno
import importlib
import os
import pkgutil
import signal
import sys
import threading
from collections.abc import Sequence
from types import ModuleType

from heartpole import files, paths
from heartpole.cli.common import CommandError

WRITE_ERRORS = frozenset({errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EACCES, errno.EPERM, errno.EFBIG, errno.EIO})
"""The ``OSError`` numbers of a place that cannot take the output (a full disk, a quota, a read-only file system,
no permission): said in one line naming the file, exit code 2."""
ONLY_WRITES_FAIL_SO = frozenset({errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EFBIG})
"""Of those, the ones only a write meets (said as ``cannot write PATH: reason``)."""

DESCRIPTION = """\
HeartPole: CartPole for health. An agent decides every half-hour of a working day whether to do
nothing, drink coffee, drink beer or sleep, trading productivity against the risk of a heart attack.

examples:
  heartpole evaluate --policy expert            # 2,000 episodes, 95% intervals, regret
  heartpole compare --policy optimal --policy expert
  heartpole baselines                           # the table of built-in policies
  heartpole optimum                             # the true optimum by dynamic programming
  heartpole train --out runs/ppo                # train an agent with Stable-Baselines3
  heartpole train --seeds 0-9 --ray             # many seeds as Ray Tune trials
  heartpole tune --algo ppo --trials 20         # a hyperparameter search with Optuna
  heartpole dataset --standard                  # Minari datasets for offline RL
  heartpole ope --dataset heartpole/v0/reference-eps20-v0 --policy expert
  heartpole plot model --out figures/           # the tutorial's curves as PNGs
  heartpole play                                # play HeartPole yourself

Run 'heartpole COMMAND --help' for each command's options.
"""


def build_parser() -> argparse.ArgumentParser:
    """The argument parser with every subcommand found in [`heartpole.cli`][heartpole.cli]."""
    parser = argparse.ArgumentParser(
        prog="heartpole", description=DESCRIPTION, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {_version()}")
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND")
    for module in _command_modules():
        module.register(subparsers)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the ``heartpole`` command with ``argv`` (default: ``sys.argv[1:]``); return the exit code.

    Ended by SIGINT (Ctrl-C), SIGTERM or SIGHUP, a command cleans up what it was writing (see
    [`heartpole.files`][heartpole.files]), says so on stderr and returns 128 + the signal's number: 130, 143 or 129,
    which says that its output is as it was. A signal that arrives once the command's new output is in place
    (complete) ends it as a success, 0. Called without ``argv`` (as the ``heartpole`` command is), a signal after
    the command returned, while Python shuts down, ends the process at once with the command's exit code.
    """
    command = ["heartpole"]
    paths.forget_outputs()
    finished: list[int] = []
    if argv is None:  # before the policy, which puts these back when it ends: no moment without them
        _exit_on_signal(finished)
    try:
        with files.signal_policy():  # first thing: from here on, a signal unwinds through every cleanup
            try:
                code = _run(argv, command)
            except KeyboardInterrupt:  # files.Interrupted, or a KeyboardInterrupt a library raised
                code = _interrupted(command)
            except Exception:
                if files.received_signal() is None:
                    raise
                # A library's cleanup failed on the way out of the signal and replaced the Interrupted
                # (torch's zip writer raises RuntimeError when its write was cut short): still a signal.
                code = _interrupted(command)
    except KeyboardInterrupt:  # another signal while saying so, or while the handlers were put back
        code = 0 if paths.outputs_placed() else files.exit_code()
    finished.append(code)
    return code


def _interrupted(command: list[str]) -> int:
    """Say how the signal ended the command; its exit code: 0 when the new output was already in place."""
    name = signal.Signals(files.exit_code() - 128).name
    if paths.outputs_placed():
        print(f"{' '.join(command)}: {name} arrived after the output was written; it is complete", file=sys.stderr)
        return 0
    print(f"{' '.join(command)}: interrupted by {name}", file=sys.stderr)
    return files.exit_code()


def _exit_on_signal(finished: list[int]) -> None:
    """Outside [`heartpole.files.signal_policy`][heartpole.signals.signal_policy] (before the command starts, and from
    its end until the process ends: Python shutting down, threads joined, modules torn down), SIGINT, SIGTERM and
    SIGHUP end the process at once: with the command's own exit code once it is in ``finished`` (the command is
    over, and its output is what that code says), else with 0 if its output is in place, else with 128 + the
    signal's number (nothing was written).
    Ignored signals stay ignored."""

    def finish(signum: int, frame: object) -> None:
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except (OSError, ValueError):
                pass
        if finished:
            os._exit(finished[0])
        if paths.outputs_placed():
            os._exit(0)
        os._exit(files.exit_code() if files.received_signal() is not None else 128 + signum)

    if threading.current_thread() is not threading.main_thread():
        return  # only the main thread may set handlers (and only it receives signals)
    for s in files.SIGNALS:
        if signal.getsignal(s) not in (signal.SIG_IGN, None):
            signal.signal(s, finish)
    atexit.register(_ignore_from_here, finish)


def _ignore_from_here(finish: object) -> None:
    """At exit, ignore the signals ``finish`` handles: Python stops running signal handlers once its ``atexit``
    callbacks are done and gives the signals their default action back (which would end a finished command
    with the signal's status while its modules are torn down); ignored signals stay ignored."""
    for s in files.SIGNALS:
        if signal.getsignal(s) is finish:
            signal.signal(s, signal.SIG_IGN)


def _run(argv: Sequence[str] | None, command: list[str]) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "handler", None):
        parser.print_help()
        return 2
    command.append(args.command)
    try:
        return int(args.handler(args) or 0)
    except CommandError as error:
        if files.received_signal() is not None:  # the signal's doing (an import it cut short): still a signal
            raise files.interruption() from error
        print(f"heartpole {args.command}: error: {error}", file=sys.stderr)
        return 2
    except OSError as error:
        if error.filename is None and error.errno in (errno.EPIPE, *WRITE_ERRORS):
            # the standard output: `heartpole evaluate | head` (the reader left: nothing more to say, exit 0) or
            # `> /dev/full`
            sys.stdout = open(os.devnull, "w")  # noqa: SIM115 - keeps Python's exit flush quiet
            if error.errno == errno.EPIPE:
                return 0
            print(
                f"heartpole {args.command}: error: cannot write the standard output: {error.strerror}", file=sys.stderr
            )
            return 2
        if error.errno not in (errno.EEXIST, *WRITE_ERRORS) or error.filename is None:
            raise
        # A full disk or a read-only file system met while writing: heartpole.files removed what it had
        # written, and named the output (not its temporary name).
        verb = "cannot write " if error.errno in ONLY_WRITES_FAIL_SO else ""
        print(f"heartpole {args.command}: error: {verb}{paths.describe_error(error)}", file=sys.stderr)
        return 2


def _command_modules() -> list[ModuleType]:
    names = sorted(m.name for m in pkgutil.iter_modules(__path__) if m.name != "common")
    modules = [importlib.import_module(f"{__name__}.{name}") for name in names]
    modules = [m for m in modules if hasattr(m, "register")]
    return sorted(modules, key=lambda m: getattr(m, "ORDER", 100))


def _version() -> str:
    from heartpole import __version__

    return __version__


if __name__ == "__main__":
    sys.exit(main())
