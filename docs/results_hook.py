"""A mkdocs hook: the committed results (``results/`` beside ``docs/``) served with the pages.

A page links a result as GitHub resolves it from ``docs/``, ``../results/compare/compare.md``; on
the site the results folder is ``results/`` beside the pages, so the hook adds every tracked file
of ``results/`` to the site's files under that path and drops one ``../`` from those links (and
``docs/`` from a result's link to a page).
"""

from __future__ import annotations

import subprocess
from pathlib import Path
from typing import Any

from mkdocs.structure.files import File, Files

ROOT = Path(__file__).resolve().parent.parent


def _tracked() -> list[str]:
    """The tracked files of ``results/`` (every file under it outside a git checkout)."""
    try:
        done = subprocess.run(
            ["git", "-C", str(ROOT), "ls-files", "-z", "results"], capture_output=True, check=True, timeout=60
        )
        names = [name for name in done.stdout.decode().split("\0") if name]
    except (OSError, subprocess.SubprocessError):
        names = []
    return names or sorted(p.relative_to(ROOT).as_posix() for p in (ROOT / "results").rglob("*") if p.is_file())


def on_files(files: Files, config: Any) -> Files:
    for name in _tracked():
        files.append(File(name, str(ROOT), config["site_dir"], config["use_directory_urls"]))
    return files


def on_page_markdown(markdown: str, page: Any, config: Any, files: Files) -> str:
    depth = page.file.src_uri.count("/")
    if page.file.src_uri.startswith("results/"):  # a result's link to a page: ../../docs/x.md is ../../x.md
        return markdown.replace("../" * depth + "docs/", "../" * depth)
    return markdown.replace("../" * (depth + 1) + "results/", "../" * depth + "results/")
