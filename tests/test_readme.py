"""Every ```python and ```bash block of the README and of every page under docs/ runs on its own, in a fresh
interpreter (a bash block: in ``bash -e``), from an empty folder.

A block opts out with an HTML comment on the line just before its fence, which the rendered page does not show:

- ``<!-- not-run: why -->``: never run here (it installs packages, starts a cluster, or regenerates a committed
  artifact for minutes; say why, and where it is checked instead);
- ``<!-- slow -->``: run in the slow tier (``pytest -m slow``), for a block that takes more than a few seconds;
- ``<!-- then -->`` (or ``<!-- slow then -->``): the block goes on from the runnable one before it on its page, as a
  walk-through does: they run in order, each in a fresh interpreter, in one folder (slow if any of them is). A
  walk-through that starts a session (``ilc-steering session new``, ``session.new``) must end with each of its
  sessions converged, as docs/your_robot.md promises a newcomer (issue 68).

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


def walks(page: Path) -> list[tuple[int, list[tuple[str, str]], bool]]:
    """(index of its first block, its blocks as (language, code), slow) of each run of a page: a block on its
    own, or a walk-through (a block and the ``then`` blocks after it)."""
    found: list[tuple[int, list[tuple[str, str]], bool]] = []
    for index, (mark, lang, code) in enumerate(blocks(page)):
        if lang not in RUN or mark.startswith("not-run"):
            continue
        words = set(mark.split())
        assert words <= {"slow", "then"}, f"{page.name}, block {index}: unknown mark <!-- {mark} -->"
        if "then" in words:
            assert found, f"{page.name}, block {index}: <!-- then --> with no runnable block before it"
            first, steps, slow = found.pop()
            found.append((first, [*steps, (lang, code)], slow or "slow" in words))
        else:
            found.append((index, [(lang, code)], "slow" in words))
    return found


def cases():
    found = []
    for page in PAGES:
        name = page.relative_to(ROOT).as_posix()
        for index, steps, slow in walks(page):
            marks = [pytest.mark.slow] if slow else []
            found.append(pytest.param(name, index, steps, id=f"{name}:{index}", marks=marks))
    return found


CASES = cases()


def test_the_readme_and_docs_have_runnable_blocks():
    assert sum(1 for case in CASES if case.values[0] == "README.md") >= 1
    assert len(CASES) >= 10
    assert any("docs/" in case.values[0] for case in CASES)
    walk = [case.values[2] for case in CASES if case.values[0] == "docs/your_robot.md" and len(case.values[2]) > 1]
    assert any("session new" in code for steps in walk for _, code in steps), "the session walk-through is gone"


def test_then_joins_a_block_to_the_one_before_it(tmp_path):
    page = tmp_path / "page.md"
    page.write_text(
        "```bash\necho a\n```\n\n<!-- then -->\n```python\nprint(1)\n```\n\n"
        "```text\nnot run\n```\n\n<!-- slow then -->\n```bash\necho b\n```\n\n```bash\necho c\n```\n"
    )
    assert walks(page) == [
        (0, [("bash", "echo a\n"), ("python", "print(1)\n"), ("bash", "echo b\n")], True),
        (4, [("bash", "echo c\n")], False),
    ]


def test_every_block_that_is_not_run_says_why():
    for page in PAGES:
        for mark, lang, _ in blocks(page):
            if mark.startswith("not-run"):
                assert lang in RUN, f"{page.name}: a ```{lang} block is never run; it needs no not-run mark"
                assert len(mark.removeprefix("not-run").strip(" :")) > 5, f"{page.name}: <!-- {mark} --> says no why"


@pytest.mark.parametrize(("page", "index", "steps"), CASES)
def test_block_runs_on_its_own(page, index, steps, tmp_path):
    env = {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}"}
    # docs/robots.md registers tests/toy_robot.py by its import name; a PYTHONPATH already set (a
    # worktree's code over an editable install of another) stays behind it
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT / "tests"), os.environ.get("PYTHONPATH")]))
    work = tmp_path / "work"
    work.mkdir()
    for step, (lang, code) in enumerate(steps):
        script = tmp_path / (f"block{step}.py" if lang == "python" else f"block{step}.sh")
        script.write_text(code)
        command = [sys.executable, str(script)] if lang == "python" else ["bash", "-e", str(script)]
        result = subprocess.run(command, capture_output=True, text=True, cwd=work, env=env, timeout=900)
        output = f"{result.stdout[-1000:]}\n{result.stderr[-2000:]}"
        where = f"block {index}" + (f", step {step + 1} of its walk-through" if len(steps) > 1 else "")
        assert result.returncode == 0, f"{page}, {where} failed:\n{code}\n{output}"
    if any("session new" in code or "session.new" in code for _, code in steps):
        from ilc_steering import session

        folders = sorted(path.parent for path in work.rglob("session.json"))
        assert folders, f"{page}, block {index}: a walk-through that starts a session left none"
        for folder in folders:
            state = session.status(folder)
            assert state.state is session.State.CONVERGED and state.exit_code == 0, (folder, state.state)
