"""Every ```python and ```bash block of the README and of every page under docs/ runs on its own, in a fresh
interpreter (a bash block: in ``bash -e``), from an empty folder.

A block opts out with an HTML comment on the line just before its fence, which the rendered page does not show:

- ``<!-- not-run: why -->``: never run here (it installs packages, starts a cluster, or regenerates a committed
  artifact for minutes; say why, and where it is checked instead);
- ``<!-- slow -->``: run in the slow tier (``pytest -m slow``), for a block that takes more than a few seconds.

A ```text (or ```toml, ```console, ...) fence is never run: use it for output and for synopses.
"""

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
FENCE = re.compile(r"(?:^<!--\s*(?P<mark>[^>]*?)\s*-->\n)?^```(?P<lang>[a-z]*)\n(?P<code>.*?)^```$", re.M | re.S)
RUN = ("python", "bash")


def blocks(path: Path) -> list[tuple[str, str, str]]:
    """(mark, language, code) of every fenced block of a page, in order."""
    return [(m["mark"] or "", m["lang"], m["code"]) for m in FENCE.finditer(path.read_text())]


def cases():
    found = []
    for page in PAGES:
        name = page.relative_to(ROOT).as_posix()
        for index, (mark, lang, code) in enumerate(blocks(page)):
            if lang not in RUN or mark.startswith("not-run"):
                continue
            assert mark in ("", "slow"), f"{name}, block {index}: unknown mark <!-- {mark} -->"
            marks = [pytest.mark.slow] if mark == "slow" else []
            found.append(pytest.param(name, index, lang, code, id=f"{name}:{index}", marks=marks))
    return found


CASES = cases()


def test_the_readme_and_docs_have_runnable_blocks():
    assert sum(1 for case in CASES if case.values[0] == "README.md") >= 1
    assert len(CASES) >= 10
    assert any("docs/" in case.values[0] for case in CASES)


def test_every_block_that_is_not_run_says_why():
    for page in PAGES:
        for mark, lang, _ in blocks(page):
            if mark.startswith("not-run"):
                assert lang in RUN, f"{page.name}: a ```{lang} block is never run; it needs no not-run mark"
                assert len(mark.removeprefix("not-run").strip(" :")) > 5, f"{page.name}: <!-- {mark} --> says no why"


@pytest.mark.parametrize(("page", "index", "lang", "code"), CASES)
def test_block_runs_on_its_own(page, index, lang, code, tmp_path):
    script = tmp_path / ("block.py" if lang == "python" else "block.sh")
    script.write_text(code)
    command = [sys.executable, str(script)] if lang == "python" else ["bash", "-e", str(script)]
    env = {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}"}
    # docs/robots.md registers tests/toy_robot.py by its import name; a PYTHONPATH already set (a
    # worktree's code over an editable install of another) stays behind it
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT / "tests"), os.environ.get("PYTHONPATH")]))
    work = tmp_path / "work"
    work.mkdir()
    result = subprocess.run(command, capture_output=True, text=True, cwd=work, env=env, timeout=900)
    output = f"{result.stdout[-1000:]}\n{result.stderr[-2000:]}"
    assert result.returncode == 0, f"{page}, block {index} failed:\n{code}\n{output}"
