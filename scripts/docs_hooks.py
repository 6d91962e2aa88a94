"""MkDocs hook (mkdocs.yml's ``hooks``): docstring examples render as code, with their prompts and output.

A docstring example is written as it runs in the doctests::

    >>> env.action_space
    Discrete(4)

Markdown reads ``>`` as a quote, so mkdocstrings would show it as three nested blockquotes with the prompts
gone and the lines run together. This hook adds a Markdown preprocessor, for the pages and for the docstrings
mkdocstrings converts with the same extensions, that turns each such example (a ``>>>`` line and the lines
after it up to a blank line or a dedent) into a fenced ``pycon`` code block, left as it is. Lines inside
fenced code blocks are left alone. tests/test_docs_site.py checks that no example on the site is prose.
"""

from __future__ import annotations

import re
from typing import Any

from markdown import Extension, Markdown
from markdown.preprocessors import Preprocessor
from mkdocs.plugins import event_priority

PROMPT = re.compile(r"^(?P<indent>[ \t]*)>>>(?: |$)")
FENCE = re.compile(r"^[ \t]*(```|~~~)")


def fence_examples(lines: list[str]) -> list[str]:
    """``lines`` with each doctest example outside a fenced block fenced as ``pycon`` code."""
    out: list[str] = []
    fence: str | None = None
    index = 0
    while index < len(lines):
        line = lines[index]
        opened = FENCE.match(line)
        if opened:
            marker = opened.group(1)
            fence = None if fence == marker else (fence or marker)
        prompt = None if fence else PROMPT.match(line)
        if prompt is None:
            out.append(line)
            index += 1
            continue
        indent = prompt.group("indent")
        end = index + 1
        while end < len(lines) and lines[end].strip() and lines[end].startswith(indent):
            end += 1
        if out and out[-1].strip():
            out.append("")  # a fence needs a blank line before it to open a block
        out += [f"{indent}```pycon", *lines[index:end], f"{indent}```"]
        if end < len(lines) and lines[end].strip():
            out.append("")
        index = end
    return out


class _Examples(Preprocessor):
    def run(self, lines: list[str]) -> list[str]:
        return fence_examples(lines)


class DoctestExamples(Extension):
    """The Markdown extension: `fence_examples` before every other preprocessor."""

    def extendMarkdown(self, md: Markdown) -> None:  # noqa: N802 - Markdown's name
        md.preprocessors.register(_Examples(md), "heartpole_doctest_examples", 40)


@event_priority(100)  # before mkdocstrings reads the extensions
def on_config(config: Any) -> Any:
    """Add `DoctestExamples` to the site's Markdown extensions (pages and docstrings alike)."""
    config.markdown_extensions.append(DoctestExamples())
    return config
