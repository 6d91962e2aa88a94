"""Packaging metadata: SPDX license, one version, no unused dependencies, typed, the sdist's contents.

The build itself (``python -m build``, ``twine check``, a wheel in a fresh venv running the CLI and the
README's quickstart) is ``scripts/check_wheel.sh``, which CI runs; these are the fast static checks.
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

import pytest

import heartpole

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    tomllib = pytest.importorskip("tomli")

ROOT = Path(__file__).resolve().parents[1]
PYPROJECT = ROOT / "pyproject.toml"
SOURCES = "\n".join(path.read_text() for path in (ROOT / "src" / "heartpole").rglob("*.py"))
# Distribution name -> the module it provides, where they differ.
MODULES = {"stable-baselines3": "stable_baselines3", "imageio-ffmpeg": "imageio_ffmpeg", "pillow": "PIL"}
# Used by another dependency on the user's behalf rather than imported here.
INDIRECT = {"moviepy": "gymnasium.wrappers.RecordVideo writes its videos with moviepy"}


@pytest.fixture(scope="module")
def project() -> dict:
    if not PYPROJECT.is_file():
        pytest.skip("not a source checkout")
    return tomllib.loads(PYPROJECT.read_text())["project"]


def test_license_is_an_spdx_expression_with_its_file(project: dict) -> None:
    assert project["license"] == "MIT"
    assert project["license-files"] == ["LICENSE"]
    assert "MIT License" in (ROOT / "LICENSE").read_text()


def test_metadata_names_authors_and_classifiers(project: dict) -> None:
    assert project["authors"]
    assert "Typing :: Typed" in project["classifiers"]
    assert not any(c.startswith("License ::") for c in project["classifiers"])  # SPDX replaces them


def test_no_metadata_names_an_address_that_is_not_the_projects(project: dict) -> None:
    """The project has no public URL or contact address: no [project.urls], no e-mail, and nothing anywhere
    in the metadata the package writes (pyproject, the datasets' Minari metadata) names pypi.org, whose
    ``heartpole`` is another package."""
    assert "urls" not in project
    assert not any("email" in author for author in project["authors"])
    assert "pypi.org" not in PYPROJECT.read_text()
    assert "pypi.org" not in SOURCES


def test_the_version_has_one_source(project: dict) -> None:
    assert "version" not in project and "version" in project["dynamic"]
    setuptools = tomllib.loads(PYPROJECT.read_text())["tool"]["setuptools"]
    assert setuptools["dynamic"]["version"] == {"attr": "heartpole.__version__"}
    assert re.fullmatch(r"\d+\.\d+\.\d+", heartpole.__version__)


def test_the_package_is_marked_typed() -> None:
    assert (Path(heartpole.__file__).parent / "py.typed").is_file()


def test_every_dependency_is_used(project: dict) -> None:
    requirements = list(project["dependencies"])
    for name, extra in project["optional-dependencies"].items():
        if name not in ("test", "docs", "all"):  # tools, run rather than imported
            requirements += extra
    for requirement in requirements:
        name = re.match(r"[A-Za-z0-9_.-]+", requirement).group(0).lower()
        if name in INDIRECT:
            continue
        module = MODULES.get(name, name.replace("-", "_"))
        assert re.search(rf"^\s*(import|from) {module}\b", SOURCES, re.MULTILINE), f"{name} is never imported"


def test_the_sdist_ships_what_tests_and_readme_need() -> None:
    manifest = (ROOT / "MANIFEST.in").read_text()
    assert "recursive-include tests *.py" in manifest  # tests/tutorial_model.py is no test_*.py
    images = set(re.findall(r"\((docs/images/[\w.-]+)\)", (ROOT / "README.md").read_text()))
    assert images and all((ROOT / image).is_file() for image in images)
    assert "recursive-include docs *.md *.png *.gif" in manifest
    assert all(Path(image).suffix in (".png", ".gif") for image in images)


def test_readme_sb3_snippets_run_pytorch_on_one_thread() -> None:
    blocks = re.findall(r"```python\n(.*?)```", (ROOT / "README.md").read_text(), re.DOTALL)
    sb3 = [block for block in blocks if "stable_baselines3" in block and ".learn(" in block]
    assert sb3
    for block in sb3:  # set before the model is built and trained
        assert "torch.set_num_threads(1)" in block.split(".learn(")[0], block
