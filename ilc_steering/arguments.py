"""The command line's argument parser: a bad argument is one line on stderr and exit 2.

:class:`argparse.ArgumentParser` answers a bad argument with the whole usage (a dozen lines for
``compare``) before the problem; here the problem comes alone, in one line that names the command
and where its usage is. Subcommands inherit the class (``add_subparsers`` makes its parsers of the
parent's type).
"""

from __future__ import annotations

import argparse
from typing import NoReturn

__all__ = ["Parser"]


class Parser(argparse.ArgumentParser):
    """An :class:`argparse.ArgumentParser` whose errors are one line: ``PROG: error: PROBLEM (see PROG --help)``."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")
