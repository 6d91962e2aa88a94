"""The house's layers: import-linter's contracts (pyproject.toml) hold, and break when an import points up or
closes a cycle; no module imports another module's ``_private`` names."""

from __future__ import annotations

import ast
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SRC = ROOT / "src"
PACKAGE = SRC / "heartpole"
LINT_IMPORTS = Path(sys.executable).with_name("lint-imports")

pytestmark = pytest.mark.skipif(not LINT_IMPORTS.exists(), reason="needs import-linter (the test extra)")


def lint_imports(project: Path) -> subprocess.CompletedProcess[str]:
    """``lint-imports`` on the package under ``project/src`` with ``project/pyproject.toml``'s contracts.

    The copy is imported from ``project/src`` (first on the path, and never the installed package): the
    check reads the files there."""
    env = {**os.environ, "PYTHONPATH": str(project / "src")}
    return subprocess.run(
        [str(LINT_IMPORTS), "--no-cache", "--config", str(project / "pyproject.toml")],
        cwd=project,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )


@pytest.fixture
def project(tmp_path: Path) -> Path:
    """A copy of the package and its contracts, to break on purpose."""
    shutil.copytree(PACKAGE, tmp_path / "src" / "heartpole", ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copy(ROOT / "pyproject.toml", tmp_path / "pyproject.toml")
    return tmp_path


def add_import(module: Path, statement: str) -> None:
    """Put ``statement`` right after ``from __future__ import annotations`` (inside a function would do too:
    import-linter reads imports wherever they are)."""
    text = module.read_text()
    future = "from __future__ import annotations\n"
    assert future in text, module
    module.write_text(text.replace(future, future + statement + "\n", 1))


def test_the_package_keeps_its_layers_and_has_no_cycles(project: Path) -> None:
    result = lint_imports(project)
    assert result.returncode == 0, result.stdout + result.stderr
    assert "Contracts: 2 kept, 0 broken." in result.stdout
    # the copy was checked, not the installed package: its module count is the copy's
    modules = len(list((project / "src" / "heartpole").rglob("*.py")))
    assert f"Analyzed {modules} files" in result.stdout


@pytest.mark.parametrize(
    ("module", "statement", "broken"),
    [
        # an upward import: the model (the bottom layer) importing the command line (the top)
        ("model.py", "import heartpole.cli", "heartpole.model is not allowed to import heartpole.cli"),
        # inside a function counts too: the policies reaching up to training
        (
            "policies/builtins.py",
            "def _load() -> object:\n    from heartpole.training import train_run\n\n    return train_run\n",
            "heartpole.policies is not allowed to import heartpole.training",
        ),
        # siblings on one layer: evaluation and plots
        ("plots/curves.py", "from heartpole.evaluation import evaluate", "heartpole.plots is not allowed to import"),
        # a cycle inside a package, where every layer is still in order
        ("policies/common.py", "import heartpole.policies.builtins", "No cycles between the modules of a package"),
    ],
)
def test_an_upward_import_or_a_cycle_breaks_the_contracts(
    project: Path, module: str, statement: str, broken: str
) -> None:
    add_import(project / "src" / "heartpole" / module, statement)
    result = lint_imports(project)
    assert result.returncode != 0, result.stdout
    assert "BROKEN" in result.stdout and broken in result.stdout, result.stdout


def test_a_new_module_must_be_given_a_layer(project: Path) -> None:
    """``exhaustive``: a module missing from the layers is an error, not a module outside the contract."""
    (project / "src" / "heartpole" / "stray.py").write_text('"""A module nobody placed."""\n')
    result = lint_imports(project)
    assert result.returncode != 0 and "heartpole.stray" in result.stdout + result.stderr


# ------------------------------------------------------------------------------------------------------
# private names


def heartpole_modules() -> dict[str, Path]:
    """Every module of the package by its dotted name (a package by its ``__init__.py``)."""
    modules = {}
    for path in PACKAGE.rglob("*.py"):
        parts = path.relative_to(SRC).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        modules[name] = path
    return modules


def private_uses(name: str, tree: ast.AST, modules: set[str]) -> list[str]:
    """Where module ``name`` uses a ``_private`` name of another HeartPole module: ``from x import _y``, or
    ``x._y`` with ``x`` bound to a HeartPole module by ``import`` (``import heartpole.x as x``,
    ``from heartpole import x``)."""
    found = []
    aliases: dict[str, str] = {}  # local name -> HeartPole module
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module is not None and node.level == 0:
            for alias in node.names:
                imported = f"{node.module}.{alias.name}"
                if imported in modules:
                    aliases[alias.asname or alias.name] = imported
                elif node.module in modules and node.module != name and _private(alias.name):
                    found.append(f"line {node.lineno}: from {node.module} import {alias.name}")
        elif isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name in modules:  # "import a.b" binds a; "import a.b as c" binds c to a.b
                    bound = alias.name if alias.asname else alias.name.split(".")[0]
                    aliases[alias.asname or bound] = bound
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and _private(node.attr):
            owner = _dotted(node.value, aliases)
            if owner in modules and owner != name:
                found.append(f"line {node.lineno}: {owner}.{node.attr}")
    return found


def _private(name: str) -> bool:
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def _dotted(node: ast.expr, aliases: dict[str, str]) -> str | None:
    """The HeartPole module an expression like ``heartpole.training`` or ``records`` names, if it names one."""
    if isinstance(node, ast.Name):
        return aliases.get(node.id)
    if isinstance(node, ast.Attribute):
        owner = _dotted(node.value, aliases)
        return None if owner is None else f"{owner}.{node.attr}"
    return None


def test_no_module_imports_another_modules_private_names() -> None:
    modules = heartpole_modules()
    offences = {
        name: uses
        for name, path in sorted(modules.items())
        if (uses := private_uses(name, ast.parse(path.read_text()), set(modules)))
    }
    assert offences == {}


@pytest.mark.parametrize(
    "source",
    [
        "from heartpole.training.outputs import _versions",
        "from heartpole import training\ntraining._versions()",
        "import heartpole.policies\nheartpole.policies._looks_like_path('x')",
        "import heartpole.registry as registry\nregistry._variants",
    ],
)
def test_the_private_name_check_sees_each_form(source: str) -> None:
    modules = set(heartpole_modules()) | {"heartpole.training.outputs"}
    assert private_uses("heartpole.jax.export", ast.parse(source), modules) != []


def test_the_private_name_check_lets_a_module_use_its_own_and_dunder_names() -> None:
    source = "import heartpole\nfrom heartpole import __version__\nheartpole.__version__\n_own = 1\n"
    assert private_uses("heartpole.records", ast.parse(source), set(heartpole_modules())) == []


def test_the_readme_layout_lists_the_contracts_layers_in_order() -> None:
    """README's Layout shows the layers of pyproject.toml's contract, top first, one line each (``a | b`` for a
    layer of several modules): moving a module in the contract without the README fails here."""
    tomllib = pytest.importorskip("tomllib")  # Python 3.11+

    contract = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["importlinter"]["contracts"][0]
    layers = [sorted(name.strip() for name in layer.split("|")) for layer in contract["layers"]]
    readme = (ROOT / "README.md").read_text()
    block = readme[readme.index("src/heartpole/   in layers") : readme.index("\ntests/ ")].splitlines()[2:]
    shown = [  # a layer's line starts one space in; descriptions and a layer's members start further in
        sorted(part.strip().split()[0].removesuffix(".py").removesuffix("/") for part in line.split("|"))
        for line in block
        if line.startswith(" ") and not line.startswith("  ")
    ]
    assert shown == [layer for layer in layers if layer != ["__main__"]]
