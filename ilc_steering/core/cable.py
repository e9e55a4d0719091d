"""A program on the other end of a cable: one JSON object per line over its stdin and stdout.

:class:`Cable` starts the program, writes a message as one line of UTF-8 JSON and reads one back
within a deadline, and writes within one too: a program that stops reading while a request bigger
than the pipe is on its way cannot hold the library past it. Whatever the program does wrong (it
cannot start, dies, hangs past the deadline, stops reading, writes half a line, a line that is not
JSON, a NaN or an infinity, a line longer than :data:`MAX_LINE` bytes) is a
:class:`~ilc_steering.errors.PlantError` whose one line names the program by its command. The
program's stderr is the library's (its log, passed through); its stdout is the protocol's alone.

The program is a child the library owns: it runs in a process group of its own, and stopping it
stops the group (what it started included). Every program started inside :func:`owned` is stopped
when that block ends, however it ends; a watcher (:func:`watch`) hears of each group as it starts
and stops, so a process that cannot run the block's end (a worker killed for its time limit) is
followed by one that stops the group for it. POSIX only (``poll`` on a pipe, process groups).
"""

from __future__ import annotations

import json
import os
import select
import shlex
import signal
import subprocess
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from contextvars import ContextVar
from typing import Any

from ilc_steering.errors import BadInput, PlantError

__all__ = ["MAX_LINE", "STOP_SECONDS", "Cable", "describe", "owned", "stop_group", "watch"]

MAX_LINE = 64 << 20
"""[bytes] the longest line read from a program (a trajectory at 1 kHz for a minute fits many times)."""
STOP_SECONDS = 5.0
"""[s] how long a program has to exit once its stdin is closed, before it is killed."""


def describe(command: Sequence[str]) -> str:
    """The program as its messages name it: ``plant process 'python robot.py'``."""
    return f"plant process {shlex.join(command)!r}"


def _no_constant(name: str) -> Any:
    raise BadInput(f"{name} is not a number JSON allows")


_OWNED: ContextVar[list[Cable] | None] = ContextVar("_OWNED", default=None)
_WATCHERS: list[Callable[[int, bool], None]] = []


@contextmanager
def owned() -> Iterator[None]:
    """Every program started inside the block is stopped when it ends: returned, raised, interrupted."""
    cables: list[Cable] = []
    token = _OWNED.set(cables)
    try:
        yield
    finally:
        _OWNED.reset(token)
        for cable in cables:
            cable.close()


def watch(callback: Callable[[int, bool], None]) -> None:
    """Call ``callback(group, started)`` as each program's process group starts (``True``) and once it
    is stopped (``False``), in this process."""
    _WATCHERS.append(callback)


def stop_group(group: int) -> None:
    """Kill every process of the process group ``group`` that is left (none: nothing happens)."""
    try:
        os.killpg(group, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        pass


def _tell(group: int, started: bool) -> None:
    for callback in _WATCHERS:
        try:
            callback(group, started)
        except (OSError, ValueError):  # a watcher whose other end has gone: nobody to tell
            pass


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
            self.process = subprocess.Popen(  # the user's own program, by design; a group of its own
                list(command),
                cwd=folder,
                stdin=subprocess.PIPE,
                stdout=subprocess.PIPE,
                bufsize=0,
                start_new_session=True,
            )
        except OSError as error:
            raise PlantError(f"{self.name}: cannot start it in {folder}: {error.strerror or error}") from None
        self.closed = False
        self._buffer = b""
        owners = _OWNED.get()
        if owners is not None:
            owners.append(self)
        _tell(self.process.pid, True)
        assert self.process.stdin is not None  # Popen with stdin=PIPE
        os.set_blocking(self.process.stdin.fileno(), False)  # written within a deadline (send)

    def fail(self, problem: str) -> PlantError:
        """A :class:`PlantError` naming the program; the program is stopped (its next answer could
        not be trusted to belong to the next request)."""
        self.close(kill=True)
        return PlantError(f"{self.name}: {problem}")

    def send(self, message: dict[str, Any], what: str, timeout: float | None = None) -> None:
        """Write ``message`` as one line, all of it taken by the program within ``timeout`` [s] (``None``:
        no limit); a program that has gone, or stops reading, is named, with ``what`` was sent."""
        data = memoryview((json.dumps(message, allow_nan=False, separators=(",", ":")) + "\n").encode("utf-8"))
        stdin = self.process.stdin
        if stdin is None or stdin.closed:
            raise self.fail(f"was stopped before {what} could be sent")
        deadline = None if timeout is None else time.monotonic() + timeout
        poller = select.poll()
        poller.register(stdin.fileno(), select.POLLOUT)
        sent = 0
        while sent < len(data):
            left = None if deadline is None else deadline - time.monotonic()
            if left is not None and left <= 0:
                raise self.fail(
                    f"stopped reading {what}: it took {sent} of its {len(data)} bytes within plant.timeout = "
                    f"{timeout:g} s (it is stopped)"
                )
            if not poller.poll(None if left is None else max(1, int(left * 1000))):
                continue
            try:
                sent += os.write(stdin.fileno(), data[sent:])
            except BlockingIOError:
                continue
            except (BrokenPipeError, ConnectionResetError):
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
            poller = select.poll()
            poller.register(fd, select.POLLIN)
            if not poller.poll(max(1, int(left * 1000))):
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
        killed; with ``kill``, at once. Either way what is left of its process group is killed."""
        process = self.process
        if process.poll() is None and not kill:
            try:
                if process.stdin is not None:
                    process.stdin.close()
                process.wait(timeout=STOP_SECONDS)
            except (OSError, subprocess.TimeoutExpired):
                pass
        stop_group(process.pid)  # the program, if it lives on, and whatever it started
        if process.poll() is None:
            process.kill()
        process.wait()
        for stream in (process.stdin, process.stdout):
            if stream is not None:
                try:
                    stream.close()
                except OSError:
                    pass
        if not self.closed:
            self.closed = True
            _tell(process.pid, False)


def _show(line: bytes) -> str:
    """The start of a line, for a message: at most 80 characters."""
    text = line.decode("utf-8", errors="replace")
    return repr(text if len(text) <= 80 else text[:80] + "...")
