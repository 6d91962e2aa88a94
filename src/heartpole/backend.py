"""Code written once and run by several backends: a module's functions with their own code objects, bound to
another backend's operations.

[`heartpole.model`][heartpole.model] (the step) and [`heartpole.rng`][heartpole.rng] (its random numbers) are
plain arithmetic on numbers whose few backend-specific operations (``exp``, a select, 32-bit integer
operations) are free names of the module. numba compiles that code and JAX traces it after those names are
bound to the backend's own operations here: no formula is written twice.
"""

from __future__ import annotations

import types
from collections.abc import Callable, Iterable, Sequence
from typing import Any


def called_by(roots: Iterable[str], namespace: dict[str, Any], bound: Iterable[str]) -> tuple[str, ...]:
    """The functions of ``namespace``'s module that ``roots`` call, directly or not, and the roots, callees first.

    Read from their code (the global names it loads, inner code included), so a helper added here and called
    from [`heartpole.model.step`][heartpole.model.step] is found without being listed anywhere. Names in ``bound`` (the
    operations a backend binds) and other modules' functions are not followed.
    """
    seen: set[str] = set(bound)
    found: list[str] = []

    def visit(name: str) -> None:
        function = namespace.get(name)
        if name in seen or not isinstance(function, types.FunctionType):
            return
        if function.__module__ != namespace["__name__"]:  # another module's function: not code to rebind
            return
        seen.add(name)
        for callee in _loaded_names(function.__code__):
            visit(callee)
        found.append(name)

    for root in roots:
        visit(root)
    return tuple(found)


def _loaded_names(code: types.CodeType) -> list[str]:
    names = list(code.co_names)
    for constant in code.co_consts:
        if isinstance(constant, types.CodeType):
            names += _loaded_names(constant)
    return names


def rebind_functions(
    namespace: dict[str, Any],
    functions: Sequence[str],
    bound: Sequence[str],
    bindings: dict[str, Any],
    constant: Callable[[Any], Any],
    wrap: Callable[[Callable[..., Any]], Any],
) -> types.SimpleNamespace:
    """``functions`` of the module whose globals are ``namespace``, with their own code objects, against
    ``bindings`` for the names in ``bound``: [`heartpole.model.rebind`][heartpole.model.rebind] and
    [`heartpole.rng.rebind`][heartpole.rng.rebind] for their modules."""
    missing = [name for name in bound if name not in bindings]
    if missing:
        raise ValueError(f"rebind needs the backend's {missing}; it binds {list(bound)}")
    rebound_namespace: dict[str, Any] = {**namespace, **bindings}
    for name in functions:
        function = namespace[name]
        code = function.__code__
        code = code.replace(co_consts=tuple(constant(c) if type(c) is float else c for c in code.co_consts))
        rebound = types.FunctionType(code, rebound_namespace, name, function.__defaults__)
        rebound.__qualname__, rebound.__module__ = function.__qualname__, function.__module__
        rebound_namespace[name] = wrap(rebound)
    return types.SimpleNamespace(**{name: rebound_namespace[name] for name in functions})
