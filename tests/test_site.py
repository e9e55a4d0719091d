"""The documentation site builds under ``mkdocs build --strict`` and renders what its sources mean:
no list that Python-Markdown ran into a paragraph (a literal ``- ``, ``* `` or ``1. `` starting a
line of a ``<p>``), no reStructuredText left in the API page's docstrings."""

from __future__ import annotations

import html
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

_CODE = re.compile(r"<(pre|code)\b[^>]*>.*?</\1>", re.S)
_PARAGRAPH = re.compile(r"<p\b[^>]*>(.*?)</p>", re.S)
_TAG = re.compile(r"<[^>]+>")
_LIST_MARKER = re.compile(r"^\s*(?:[-*]|\d+\.) ")
_RST = {token: re.escape(token) for token in (":math:", ".. math::", ":class:", ":func:", ":meth:")}
_RST["``literal``"] = r"``[^`\n]+``"


def _problems(page: str, text: str) -> list[str]:
    text = _CODE.sub("", text)
    found = []
    for paragraph in _PARAGRAPH.findall(text):
        for line in paragraph.split("\n"):
            plain = html.unescape(_TAG.sub("", line))
            if _LIST_MARKER.match(plain):
                found.append(f"{page}: literal list marker in a paragraph: {plain.strip()[:100]!r}")
    plain = html.unescape(_TAG.sub("", text))
    for token, pattern in _RST.items():
        for m in re.finditer(pattern, plain):
            snippet = plain[max(0, m.start() - 40) : m.end() + 60].replace("\n", " ")
            found.append(f"{page}: raw reST {token!r}: {snippet!r}")
    return found


def test_scanner_finds_what_it_looks_for():
    bad = "<p>an item:\n- run together</p><p>see :math:`x` and ``y``</p><pre>- code is fine ``z``</pre>"
    found = _problems("bad.html", bad)
    assert len(found) == 3, found
    assert _problems("good.html", "<p>a - b</p><ul><li>item</li></ul><code>:func:`f`</code>") == []


@pytest.mark.slow
def test_site_builds_strict_and_renders(tmp_path):
    site = tmp_path / "site"
    done = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(site)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        env={**os.environ, "NO_MKDOCS_2_WARNING": "1"},
    )
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    pages = sorted(site.rglob("*.html"))
    assert any(p.name == "api.html" for p in pages)
    found = []
    for page in pages:
        found += _problems(str(page.relative_to(site)), page.read_text(encoding="utf-8"))
    assert not found, "\n".join(found[:40])
