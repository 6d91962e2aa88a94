"""What every ``heartpole`` subcommand shares: errors, argument types, tables and output checks.

Files are written by [`heartpole.files`][heartpole.files] (whole or not at all).
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import NoReturn, TypeAlias

from heartpole import paths
from heartpole.stats import fixed

Subparsers: TypeAlias = "argparse._SubParsersAction[argparse.ArgumentParser]"
"""What ``register(subparsers)`` of each command module receives: ``ArgumentParser.add_subparsers()``."""


class CommandError(Exception):
    """A problem the user can fix; printed as one line on stderr with exit code 2."""


def error_line(error: Exception) -> str:
    """A library's error as one line: an ``OSError`` about a file as ``PATH: reason`` (never ``[Errno 28]`` and a
    quoted name), anything else its message with the line breaks folded."""
    if isinstance(error, OSError) and error.errno is not None and error.filename is not None:
        return paths.describe_error(error)
    return " ".join(str(error).split())


def tell_normalization(policy: object) -> None:
    """Say on stderr which saved observation statistics a loaded model applies, if any."""
    path = getattr(policy, "normalizer_path", None)
    if path is not None:
        print(
            f"note: {getattr(policy, 'name', 'the model')} normalises observations with {path} (recorded with it)",
            file=sys.stderr,
        )


def not_empty(option: str, value: str | None) -> str | None:
    """``value`` unless it is the empty string, which names nothing (``--out ''`` must not quietly mean the
    default): ``CommandError`` naming ``option``."""
    if value is not None and not value.strip():
        raise CommandError(f"{option} must name something, got {value!r}; omit {option} to get its default")
    return value


TRUST_PICKLES_HELP = (
    "load a model file by unpickling it (Stable-Baselines3's load, pickle) where HeartPole's safe readers refuse "
    "it; unpickling can run any code the file's author chose: only for files you trust"
)


def add_trust_pickles(parser: argparse.ArgumentParser) -> None:
    """Add ``--trust-pickles`` (``args.trust_pickles``) to a command that loads models."""
    parser.add_argument("--trust-pickles", action="store_true", help=TRUST_PICKLES_HELP)


def positive_int(text: str) -> int:
    """argparse type: an integer >= 1."""
    try:
        value = int(text)
    except ValueError:
        raise_arg(f"expected a whole number >= 1, got {text!r}")
    if value < 1:
        raise_arg(f"expected a whole number >= 1, got {value}")
    return value


def at_least(minimum: int) -> Callable[[str], int]:
    """argparse type: an integer >= ``minimum``, refused by the parser with the option's name (``argument --grid:
    expected a whole number >= 4, got 1``) rather than later by the library without it."""

    def whole(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise_arg(f"expected a whole number >= {minimum}, got {text!r}")
        if value < minimum:
            raise_arg(f"expected a whole number >= {minimum}, got {value}")
        return value

    whole.__name__ = f"whole number >= {minimum}"  # argparse names the type in its own messages
    return whole


def seed_int(text: str) -> int:
    """argparse type: a seed, an integer >= 0."""
    try:
        value = int(text)
    except ValueError:
        raise_arg(f"expected a seed (a whole number >= 0), got {text!r}")
    if value < 0:
        raise_arg(f"expected a seed (a whole number >= 0), got {value}")
    return value


def raise_arg(message: str) -> None:
    import argparse

    raise argparse.ArgumentTypeError(message)


def format_table(headers: Sequence[str], rows: Sequence[Sequence[object]]) -> str:
    """A plain-text table with right-aligned numbers, for the terminal.

    >>> print(format_table(["policy", "score"], [["expert", 0.3268], ["nothing", 0.15]]))
    policy   score
    -------  -----
    expert   0.327
    nothing  0.150
    """
    cells = [[str(h) for h in headers]] + [[_cell(v) for v in row] for row in rows]
    widths = [max(len(row[i]) for row in cells) for i in range(len(headers))]
    lines = []
    for n, row in enumerate(cells):
        lines.append("  ".join(c.rjust(w) if n and _is_number(c) else c.ljust(w) for c, w in zip(row, widths)))
        if n == 0:
            lines.append("  ".join("-" * w for w in widths))
    return "\n".join(line.rstrip() for line in lines)


def markdown_table(headers: Sequence[str], rows: Sequence[Sequence[object]]) -> str:
    """The same table in GitHub Markdown."""
    lines = ["| " + " | ".join(map(str, headers)) + " |", "|" + "---|" * len(headers)]
    lines += ["| " + " | ".join(_cell(v) for v in row) + " |" for row in rows]
    return "\n".join(lines)


def _cell(value: object) -> str:
    if isinstance(value, float):
        return f"{value:.4g}" if abs(value) < 1e-3 and value != 0 else fixed(value, 3)
    return str(value)


def _is_number(text: str) -> bool:
    try:
        float(text.split(" ")[0])
        return True
    except ValueError:
        return False


def output_file(path: str | os.PathLike[str], *, force: bool, suffixes: Sequence[str] | None = None) -> Path:
    """Check, before any work, that the file ``path`` may be written; return it as a ``Path``.

    Every command that writes behaves alike: missing folders are created (when written, by
    [`heartpole.files.atomic_files`][heartpole.files.atomic_files]), an existing file is replaced only with ``--force``,
    and files and folders get the modes the umask gives.

    Raises:
        CommandError: an unaccepted suffix, a folder in the way, an existing file without ``force``, or a
            place the file cannot be written (no permission, a read-only file system, a name too long: see
            [`writable`][heartpole.cli.common.writable]).
    """
    not_empty("--out", os.fspath(path))
    target = paths.followed(path)  # a symbolic link: the file it leads to is written, the link stays
    if suffixes is not None and target.suffix.lower() not in suffixes:
        suffix = target.suffix or "(none)"
        raise CommandError(f"{target}: unsupported file type {suffix!r}; use one of {list(suffixes)}")
    if target.is_dir():
        raise CommandError(f"{target} is a folder, expected a file path")
    if target.exists() and not force:
        raise CommandError(f"{target} exists; pass --force to replace it")
    existing = _nearest_existing(target.parent)
    if not existing.is_dir():
        raise CommandError(f"{target}: {existing} is a file, not a folder")
    writable(target)
    paths.expect_output(target, replace=force)
    return target


def writable(target: str | os.PathLike[str]) -> Path:
    """[`heartpole.paths.check_writable`][heartpole.paths.check_writable] as a one-line
    [`CommandError`][heartpole.cli.common.CommandError]: ``cannot write PATH: Read-only file system``."""
    try:
        return paths.check_writable(target)
    except OSError as error:
        raise CommandError(f"cannot write {paths.describe_error(error)}") from None


def output_files(folder: str | os.PathLike[str], names: Sequence[str], *, force: bool) -> list[Path]:
    """[`output_file`][heartpole.cli.common.output_file] for each of ``names`` in ``folder`` (created when written if
    missing)."""
    not_empty("--out", os.fspath(folder))
    base = Path(folder)
    if base.exists() and not base.is_dir():
        raise CommandError(f"{base} is a file, expected a folder")
    return [output_file(base / name, force=force) for name in names]


def _nearest_existing(folder: Path) -> Path:
    folder = folder if str(folder) else Path(".")
    while not folder.exists() and folder != folder.parent:
        folder = folder.parent
    return folder


def add_people_arguments(parser: argparse.ArgumentParser, what: str) -> None:
    """``--people NAME`` and ``--observe-traits``, the same on every command that runs episodes; ``what`` says
    what the command does with the people."""
    parser.add_argument(
        "--people",
        default=None,
        metavar="NAME",
        help=f"a population of people, one drawn per episode (named: default); {what}",
    )
    parser.add_argument(
        "--observe-traits", action="store_true", help="append each person's traits to the observation (--people)"
    )


def one_line_error(parser: argparse.ArgumentParser, message: str) -> NoReturn:
    """A subcommand's argument errors as one line on stderr and exit code 2, without argparse's usage block.
    Install with ``parser.error = types.MethodType(one_line_error, parser)``."""
    print(f"{parser.prog}: error: {message} (see {parser.prog} --help)", file=sys.stderr)
    raise SystemExit(2)


def env_id_type(text: str) -> str:
    """``--env``'s value if it is a HeartPole id: a ``module:Name-v0`` id would make Gymnasium import ``module``
    (from the current folder too), so the command line takes HeartPole's ids only (the Python API takes any)."""
    from heartpole.registry import check_heartpole_id  # Gymnasium's registry: imported when an --env is given

    try:
        return check_heartpole_id(text, "--env")
    except ValueError as error:
        raise argparse.ArgumentTypeError(str(error).removeprefix("--env: ")) from None


def heartpole_env(env_id: str) -> str:
    """``env_id`` if it is a HeartPole id, else a one-line [`CommandError`][heartpole.cli.common.CommandError] (see
    [`env_id_type`][heartpole.cli.common.env_id_type]), for the commands that check their arguments as they run."""
    try:
        return env_id_type(env_id)
    except argparse.ArgumentTypeError as error:
        raise CommandError(f"--env: {error}") from None
