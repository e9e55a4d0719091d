"""A program on the other end of a cable: one JSON object per line over its stdin and stdout.

:class:`Cable` starts the program, writes a message as one line of UTF-8 JSON and reads one back
within a deadline. Whatever the program does wrong (it cannot start, dies, hangs past the
deadline, writes half a line, a line that is not JSON, a NaN or an infinity, a line longer than
:data:`MAX_LINE` bytes) is a :class:`~ilc_steering.errors.PlantError` whose one line names the
program by its command. The program's stderr is the library's (its log, passed through); its
stdout is the protocol's alone. POSIX only (``select`` on a pipe).
"""

from __future__ import annotations

import json
import os
import select
import shlex
import subprocess
import time
from collections.abc import Sequence
from typing import Any

from ilc_steering.errors import BadInput, PlantError

__all__ = ["MAX_LINE", "STOP_SECONDS", "Cable", "describe"]

MAX_LINE = 64 << 20
"""[bytes] the longest line read from a program (a trajectory at 1 kHz for a minute fits many times)."""
STOP_SECONDS = 5.0
"""[s] how long a program has to exit once its stdin is closed, before it is killed."""


def describe(command: Sequence[str]) -> str:
    """The program as its messages name it: ``plant process 'python robot.py'``."""
    return f"plant process {shlex.join(command)!r}"


def _no_constant(name: str) -> Any:
    raise BadInput(f"{name} is not a number JSON allows")


class Cable:
    """A running program and the lines exchanged with it.

    Parameters
    ----------
    command
        The program and its arguments (``argv``), started in ``folder``.
    folder
        Its working directory.
    """

    def __init__(self, command: Sequence[str], folder: str) -> None:
        self.name = describe(command)
        try:
            self.process = subprocess.Popen(  # the user's own program, by design
                list(command), cwd=folder, stdin=subprocess.PIPE, stdout=subprocess.PIPE, bufsize=0
            )
        except OSError as error:
            raise PlantError(f"{self.name}: cannot start it in {folder}: {error.strerror or error}") from None
        self._buffer = b""

    def fail(self, problem: str) -> PlantError:
        """A :class:`PlantError` naming the program; the program is stopped (its next answer could
        not be trusted to belong to the next request)."""
        self.close(kill=True)
        return PlantError(f"{self.name}: {problem}")

    def send(self, message: dict[str, Any], what: str) -> None:
        """Write ``message`` as one line; a program that has gone is named, with ``what`` was sent."""
        line = json.dumps(message, allow_nan=False, separators=(",", ":")) + "\n"
        stdin = self.process.stdin
        try:
            assert stdin is not None  # Popen with stdin=PIPE
            stdin.write(line.encode("utf-8"))
            stdin.flush()
        except (BrokenPipeError, ConnectionResetError, ValueError):
            raise self.fail(f"died before {what} could be sent ({self._exit()})") from None

    def receive(self, timeout: float, what: str) -> dict[str, Any]:
        """The next line, as a JSON object, within ``timeout`` [s]; ``what`` is what was awaited."""
        line = self._line(time.monotonic() + timeout, timeout, what)
        try:
            message = json.loads(line.decode("utf-8"), parse_constant=_no_constant)
        except (UnicodeDecodeError, ValueError) as error:
            raise self.fail(f"answered {what} with a line that is not JSON ({error}): {_show(line)}") from None
        if not isinstance(message, dict):
            raise self.fail(f"answered {what} with JSON that is not an object: {_show(line)}")
        return message

    def _line(self, deadline: float, timeout: float, what: str) -> bytes:
        stdout = self.process.stdout
        assert stdout is not None  # Popen with stdout=PIPE
        fd = stdout.fileno()
        while b"\n" not in self._buffer:
            left = deadline - time.monotonic()
            if left <= 0:
                half = f" after half a line ({len(self._buffer)} bytes: {_show(self._buffer)})" if self._buffer else ""
                raise self.fail(f"gave no answer to {what} within plant.timeout = {timeout:g} s{half}")
            ready, _, _ = select.select([fd], [], [], left)
            if not ready:
                continue
            chunk = os.read(fd, 1 << 16)
            if not chunk:
                if self._buffer:
                    raise self.fail(
                        f"wrote half a line ({_show(self._buffer)}, no newline) and closed its stdout "
                        f"instead of answering {what} ({self._exit()})"
                    )
                status = self._exit()
                if status == "it is still running":
                    raise self.fail(f"closed its stdout before answering {what} (it was still running; it is stopped)")
                raise self.fail(f"died before answering {what} ({status})")
            self._buffer += chunk
            if len(self._buffer) > MAX_LINE:
                raise self.fail(f"answered {what} with a line over {MAX_LINE} bytes")
        line, _, self._buffer = self._buffer.partition(b"\n")
        return line

    def _exit(self) -> str:
        try:
            code = self.process.wait(timeout=1.0)
        except subprocess.TimeoutExpired:
            return "it is still running"
        return f"exit status {code}" if code >= 0 else f"killed by signal {-code}"

    def close(self, kill: bool = False) -> None:
        """End the program: its stdin closed (the end of the run), :data:`STOP_SECONDS` to exit, then
        killed; with ``kill``, at once."""
        process = self.process
        if process.poll() is None and not kill:
            try:
                if process.stdin is not None:
                    process.stdin.close()
                process.wait(timeout=STOP_SECONDS)
            except (OSError, subprocess.TimeoutExpired):
                pass
        if process.poll() is None:
            process.kill()
            process.wait()
        for stream in (process.stdin, process.stdout):
            if stream is not None:
                try:
                    stream.close()
                except OSError:
                    pass


def _show(line: bytes) -> str:
    """The start of a line, for a message: at most 80 characters."""
    text = line.decode("utf-8", errors="replace")
    return repr(text if len(text) <= 80 else text[:80] + "...")
