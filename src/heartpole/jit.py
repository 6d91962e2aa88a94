"""numba's options for HeartPole's compiled code (its disk cache, the options every ``njit`` passes) and three
small tools of its loops over envs: [`one`][heartpole.jit.one], [`wide_vectors`][heartpole.jit.wide_vectors] and
[`no_alias`][heartpole.jit.no_alias].

Compiled code is cached on disk (numba's ``cache=True``): the first use after an install compiles for a
few seconds, later processes load it. Where numba can write nowhere (a read-only install run by a user with
no writable home) the step compiles in memory in every process, with one warning naming ``NUMBA_CACHE_DIR``.
"""

from __future__ import annotations

import hashlib
import types
import warnings
from pathlib import Path
from typing import Any, Literal, TypedDict

import numba
import numpy as np
from numba import njit
from numba.core import cgutils
from numba.core import types as nbtypes
from numba.extending import intrinsic
from numba.np.numpy_support import carray as _carray


class JitOptions(TypedDict):
    """The type of `JIT`: keyword arguments of ``numba.njit``."""

    cache: bool
    error_model: Literal["python", "numpy"]
    nogil: bool
    fastmath: set[str]


class InlineOptions(TypedDict):
    """The type of `INLINE`: keyword arguments of ``numba.njit``."""

    inline: Literal["never", "always"]


CACHE_WARNING = (
    "HeartPole compiles its step in memory, again in every process (a few seconds): numba finds no writable "
    "folder to cache compiled code in (beside the installed package, or the user's cache). Set NUMBA_CACHE_DIR "
    "to a writable folder to keep it."
)
"""The one warning of an install that numba cannot cache beside, run by a user with no writable home."""


def _cacheable() -> bool:
    """Whether numba can cache this module's compiled code on disk, asked of numba itself.

    numba picks a folder when a function is decorated with ``cache=True``: ``$NUMBA_CACHE_DIR`` if set,
    else ``__pycache__`` beside the source, else the user's cache (``~/.cache/numba``); with none writable
    (a read-only install, no writable home) the decoration raises ``RuntimeError``. This probe makes that
    choice once, for this very file, so the import never fails: compiled code then lives in memory only.
    """
    try:
        njit(cache=True)(_cacheable)
    except RuntimeError:
        warnings.warn(CACHE_WARNING, RuntimeWarning, stacklevel=3)
        return False
    return True


CACHE = _cacheable()
"""Whether numba caches compiled code on disk here: every ``njit`` of the package passes ``cache=CACHE``."""

JIT: JitOptions = {
    "cache": CACHE,
    "error_model": "numpy",
    "nogil": True,
    "fastmath": {"contract", "arcp"},
}
"""numba options for everything here: cached on disk where numba can write (`_cacheable`); division
follows NumPy (no ZeroDivisionError
checks, which stop LLVM from vectorising); the GIL is released. Two of LLVM's fast-math liberties, no
others: ``contract`` fuses a multiply and an add into one instruction (rounded once), ``arcp`` divides by
a constant as a multiplication by its reciprocal; infinities, NaNs and the order of operations stay
IEEE's. What they earn: docs/speed.md, "What each mechanism of the loop earned"."""

INLINE: InlineOptions = {"inline": "always"}
"""numba compiles each function on its own and calls it through its own calling convention, which LLVM
cannot inline; the model's functions are inlined at numba's level instead, so that the loop over envs
is one straight stretch of arithmetic that LLVM can vectorise."""


def cache_keyed_on(source: types.ModuleType, *dispatchers: Any) -> None:
    """Key the disk cache of ``dispatchers`` on the file of ``source`` too, not only on their own file.

    numba throws a function's cached code away when the file that defines it changes. The kernel's loops
    inline [`heartpole.model`][heartpole.model]'s step, so an edit of model.py alone would leave them running
    the old step from the cache. This adds a hash of that file to the stamp numba checks (its cache file's
    ``_source_stamp``, an internal: a numba without it keys the cache as numba does).
    """
    if source.__file__ is None:
        return
    digest = hashlib.sha256(Path(source.__file__).read_bytes()).hexdigest()
    for dispatcher in dispatchers:
        cache_file = getattr(getattr(dispatcher, "_cache", None), "_cache_file", None)
        if cache_file is not None and hasattr(cache_file, "_source_stamp"):
            cache_file._source_stamp = (cache_file._source_stamp, digest)


# numba's stubs type these as outside compiled code; called from compiled code here, they are held as Any.
carray: Any = _carray
alloca_once: Any = cgutils.alloca_once


@intrinsic
def _on_the_stack_intrinsic(typingctx: Any, value: Any, like: Any) -> Any:
    """A pointer to room for ``len(like)`` values like ``value`` (``like`` a tuple) on the stack of the compiled
    function that calls it."""

    def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
        return alloca_once(builder, context.get_data_type(value), size=len(like))

    pointer: Any = nbtypes.CPointer
    return pointer(value)(value, like), codegen


_on_the_stack: Any = _on_the_stack_intrinsic


@njit(**JIT, **INLINE)
def one(value: Any) -> Any:
    """A one-item array holding ``value``, on the caller's stack (no allocation)."""
    array = carray(_on_the_stack(value, (value,)), 1)
    array[0] = value
    return array


@njit(**JIT, **INLINE)
def column(like: Any) -> Any:
    """A ``(len(like), 1)`` array of the type of ``like``'s items (a tuple), on the caller's stack, uninitialised."""
    return carray(_on_the_stack(like[0], like), (len(like), 1))


if numba.config.DISABLE_JIT:  # type: ignore[attr-defined]
    one = lambda value: np.full(1, value)  # type: ignore[assignment]  # noqa: E731
    column = lambda like: np.zeros((len(like), 1), dtype=type(like[0]))  # type: ignore[assignment]  # noqa: E731


VECTOR_WIDTH = 512
"""The vector width, in bits, LLVM may use for the loop over envs (``prefer-vector-width``). On CPUs with
AVX-512 LLVM otherwise keeps to 256 bits (what 512 earns: docs/speed.md). CPUs without AVX-512 ignore it. It
is an attribute of the loop's own function, not a process-wide option."""


@intrinsic
def _wide_vectors_intrinsic(typingctx: Any) -> Any:
    """Let LLVM vectorise the calling function `VECTOR_WIDTH` bits wide (no code of its own)."""

    def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
        # llvmlite knows only LLVM's keyword attributes; a string attribute goes into the set as written
        set.add(builder.function.attributes, f'"prefer-vector-width"="{VECTOR_WIDTH}"')
        return context.get_dummy_value()

    return nbtypes.none(), codegen


wide_vectors: Any = _wide_vectors_intrinsic
"""Called first in a loop's compiled function: LLVM may vectorise that function `VECTOR_WIDTH` bits wide."""
if numba.config.DISABLE_JIT:  # type: ignore[attr-defined]
    wide_vectors = lambda: None  # noqa: E731


@intrinsic
def _no_alias_intrinsic(typingctx: Any) -> Any:
    """Tell LLVM that no two pointer arguments of the calling function overlap (``noalias``, which numba's own
    ``noalias`` flag adds for its parallel loops): it then vectorises a loop that reads some arrays and writes
    others without checks at run time (with them, it gives up: too many pairs of arrays to check)."""

    def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
        for argument in context.call_conv.get_arguments(builder.function):
            if argument.type.is_pointer:
                argument.add_attribute("noalias")
        return context.get_dummy_value()

    return nbtypes.none(), codegen


no_alias: Any = _no_alias_intrinsic
"""Called first in a loop's compiled function: its array arguments do not overlap. The loops' callers pass arrays
of their own (the states, generator states and cells of their envs, fresh results and observations)."""
if numba.config.DISABLE_JIT:  # type: ignore[attr-defined]
    no_alias = lambda: None  # noqa: E731
