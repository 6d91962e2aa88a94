"""The documentation site builds strictly, and the build fails on a broken reference (the check can fail)."""

from __future__ import annotations

import ast
import html
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("mkdocstrings")

ROOT = Path(__file__).resolve().parents[1]
MKDOCS = str(Path(sys.executable).with_name("mkdocs"))


def build(root: Path, site: Path) -> subprocess.CompletedProcess[str]:
    """``scripts/build_docs.sh`` of the tree at ``root``, as CI runs it."""
    environment = {**os.environ, "MKDOCS": MKDOCS}
    command = ["bash", str(root / "scripts" / "build_docs.sh"), str(site)]
    return subprocess.run(command, env=environment, capture_output=True, text=True, timeout=300)


def copy_of_the_docs(destination: Path) -> Path:
    """What the site is built from: mkdocs.yml, docs/, the sources the API pages read, README and scripts."""
    destination.mkdir()
    for name in ("mkdocs.yml", "README.md", "CHANGELOG.md"):
        shutil.copy(ROOT / name, destination / name)
    for name in ("docs", "src", "scripts"):
        shutil.copytree(ROOT / name, destination / name, ignore=shutil.ignore_patterns("__pycache__"))
    return destination


@pytest.fixture(scope="module")
def site(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The site as CI builds it, once for the tests that read it."""
    folder = tmp_path_factory.mktemp("built") / "site"
    done = build(ROOT, folder)
    assert done.returncode == 0, done.stderr[-3000:]
    assert "WARNING" not in done.stderr, done.stderr[-3000:]
    return folder


def test_the_site_builds_strictly_without_a_warning(site: Path) -> None:
    assert (site / "api" / "index.html").is_file()
    assert (site / "api" / "model" / "index.html").is_file()


RAW_ROLE = re.compile(r":(?:py:)?(?:func|class|mod|data|meth|attr|obj|exc|const|ref):(?:`|<code>)")
"""A reStructuredText role as Sphinx writes it (in a source), or as Markdown renders it (the role's name as
literal text before the code: ``:func:<code>step</code>``)."""


def test_no_page_shows_a_raw_sphinx_role(site: Path) -> None:
    shown = {str(page.relative_to(site)): RAW_ROLE.findall(page.read_text()) for page in site.rglob("*.html")}
    assert {page: found for page, found in shown.items() if found} == {}


def test_the_raw_role_check_can_fail(tmp_path: Path) -> None:
    page = tmp_path / "index.html"
    page.write_text("<p>:func:<code>heartpole.model.step</code> runs one step</p>")
    assert RAW_ROLE.findall(page.read_text())


def test_every_cross_reference_in_the_sources_is_a_link() -> None:
    """No docstring or comment in the package writes a Sphinx role (the site renders them raw)."""
    written = {
        str(path.relative_to(ROOT)): RAW_ROLE.findall(path.read_text())
        for path in (ROOT / "src" / "heartpole").rglob("*.py")
    }
    assert {path: found for path, found in written.items() if found} == {}


def test_every_module_has_its_api_page() -> None:
    """Every module of the package (but the command line's, documented by its ``--help``) is rendered on
    one of the API pages, so a reference to anything public in it resolves."""
    rendered = set(
        re.findall(
            r"^::: (heartpole[\w.]*)",
            "".join(page.read_text() for page in (ROOT / "docs" / "api").glob("*.md")),
            flags=re.M,
        )
    )
    source = ROOT / "src"
    modules = {
        ".".join(path.relative_to(source).with_suffix("").parts).removesuffix(".__init__")
        for path in (source / "heartpole").rglob("*.py")
    }
    expected = {name for name in modules if not name.startswith("heartpole.cli") and name != "heartpole.__main__"}
    assert sorted(expected - rendered) == []


@pytest.mark.slow  # two strict builds of the site (about 4 s each): CI's slow stage shows the check can fail
@pytest.mark.parametrize(
    "where, breakage",
    [
        ("src/heartpole/evaluation.py", "See [the interval][heartpole.stats.no_such_function]."),
        ("docs/evaluation.md", "See [the missing page](no-such-page.md)."),
    ],
)
def test_a_broken_reference_fails_the_build(tmp_path: Path, where: str, breakage: str) -> None:
    root = copy_of_the_docs(tmp_path / "tree")
    path = root / where
    text = path.read_text()
    if where.endswith(".py"):  # into the module's docstring, which the API page renders
        first = text.index('"""') + 3
        text = text[:first] + breakage + "\n\n" + text[first:]
    else:
        text += "\n" + breakage + "\n"
    path.write_text(text)
    done = build(root, tmp_path / "site")
    assert done.returncode != 0, "a broken reference passed the strict build"
    assert "no_such_function" in done.stderr or "no-such-page.md" in done.stderr, done.stderr[-3000:]


# ------------------------------------------------------------------------------------- docstring examples
PRE = re.compile(r"<pre[^>]*>(.*?)</pre>", re.S)
NESTED_QUOTES = re.compile(r"<blockquote>\s*<blockquote>")
"""A doctest example rendered as prose: Markdown reads ``>>>`` as three nested quotes."""


def shown_as_code(page: str) -> str:
    """The text of a page's code blocks, as a reader sees it (tags dropped, entities decoded)."""
    return "\n".join(html.unescape(re.sub(r"<[^>]+>", "", block)) for block in PRE.findall(page))


def docstring_examples() -> dict[str, list[str]]:
    """Every ``>>>`` line of every docstring in the package, by module path."""
    found: dict[str, list[str]] = {}
    for path in sorted((ROOT / "src" / "heartpole").rglob("*.py")):
        if "cli" in path.parts or path.name == "__main__.py":
            continue
        tree = ast.parse(path.read_text())
        nodes = [tree, *(n for n in ast.walk(tree) if isinstance(n, (ast.ClassDef, ast.FunctionDef)))]
        lines = [
            line.strip()
            for node in nodes
            for line in (ast.get_docstring(node) or "").splitlines()
            if line.strip().startswith(">>>")
        ]
        if lines:
            found[str(path.relative_to(ROOT))] = lines
    return found


def examples_shown_as_prose(site: Path) -> dict[str, int]:
    """The pages that show an example as nested quotes, with how many."""
    counts = {str(p.relative_to(site)): len(NESTED_QUOTES.findall(p.read_text())) for p in site.rglob("*.html")}
    return {page: count for page, count in counts.items() if count}


def test_every_docstring_example_renders_as_code_with_its_prompts(site: Path) -> None:
    assert examples_shown_as_prose(site) == {}
    assert [str(p) for p in site.rglob("*.html") if "```pycon" in p.read_text()] == []  # no fence shown as text
    code = "\n".join(shown_as_code(page.read_text()) for page in (site / "api").rglob("*.html"))
    examples = docstring_examples()
    assert sum(map(len, examples.values())) > 50  # the package's examples were found (78 lines today)
    missing = {path: [line for line in lines if line not in code] for path, lines in examples.items()}
    assert {path: lines for path, lines in missing.items() if lines} == {}


def test_the_example_check_can_fail(tmp_path: Path) -> None:
    """An example as mkdocstrings showed it before the hook: nested quotes, the prompts gone."""
    (tmp_path / "index.html").write_text(
        "<blockquote>\n<blockquote>\n<blockquote>\n<p>import heartpole env.action_space Discrete(4)</p>"
        "</blockquote>\n</blockquote>\n</blockquote>"
    )
    assert examples_shown_as_prose(tmp_path) == {"index.html": 1}
    assert ">>> env.action_space" not in shown_as_code((tmp_path / "index.html").read_text())
