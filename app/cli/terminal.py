"""The command's words on a stream that can go away — a closed terminal, an ssh session dropped, a
pipe whose reader stopped (``c2n live | head``), a full disk behind ``> out.txt``, standard output
closed (``1>&-``). Losing where the words go must not end the work they describe: a live session
goes on recording what the bus carries. So the console writes through a ``LosableStream``, which
remembers the first failure and drops what comes after it.
"""

import contextlib
import errno
import io
import os
import sys
from typing import TextIO, cast


class LosableStream(io.TextIOBase):
    """A text stream over ``stream`` (None: one that was closed before the command began). The
    first write or flush that fails is kept in ``lost``; it and every later write are dropped."""

    def __init__(self, stream: TextIO | None) -> None:
        super().__init__()
        self.stream = stream
        self.lost: OSError | None = None if stream is not None else OSError(errno.EBADF, "closed")

    @property
    def encoding(self) -> str:  # type: ignore[override]  # rich reads it to choose its characters
        return getattr(self.stream, "encoding", None) or "utf-8"

    def writable(self) -> bool:
        return True

    def isatty(self) -> bool:
        if self.lost is not None or self.stream is None:
            return False
        try:
            return self.stream.isatty()
        except (OSError, ValueError):
            return False

    def fileno(self) -> int:
        if self.stream is None:
            raise io.UnsupportedOperation("closed before the command began")
        return self.stream.fileno()

    def write(self, text: str) -> int:
        if self.lost is None and self.stream is not None:
            try:
                self.stream.write(text)
            except (OSError, ValueError) as error:
                self._lose(error)
        return len(text)

    def flush(self) -> None:
        if self.lost is None and self.stream is not None:
            try:
                self.stream.flush()
            except (OSError, ValueError) as error:
                self._lose(error)

    def _lose(self, error: OSError | ValueError) -> None:
        self.lost = error if isinstance(error, OSError) else OSError(errno.EBADF, str(error))
        if self.stream is not None:
            _quiet(self.stream)

    @property
    def why(self) -> str:
        """The loss in words (``Input/output error``), empty while nothing was lost."""
        if self.lost is None:
            return ""
        return self.lost.strerror or str(self.lost)

    @property
    def reader_left(self) -> bool:
        """The stream was a pipe whose reader stopped reading (``| head``): no one wants more."""
        return self.lost is not None and self.lost.errno == errno.EPIPE


def _quiet(stream: TextIO) -> None:
    """Point a lost standard stream at the null device, so that what its buffer still holds does
    not fail again when the interpreter flushes it at exit (Python's own advice for SIGPIPE)."""
    if stream not in (sys.stdout, sys.stderr, sys.__stdout__, sys.__stderr__):
        return
    try:
        null = os.open(os.devnull, os.O_WRONLY)
        try:
            os.dup2(null, stream.fileno())
        finally:
            os.close(null)
    except (OSError, ValueError, AttributeError):  # no descriptor to point anywhere
        pass


def say(text: str) -> None:
    """One line on standard error, if it is still there (None: closed before the command began)."""
    with contextlib.suppress(OSError, ValueError, AttributeError):
        print(text, file=sys.stderr, flush=True)


def console_stream(stream: TextIO | None) -> TextIO:
    """``stream`` as a rich Console's file, losable (rich's annotation asks for a TextIO)."""
    return cast(TextIO, LosableStream(stream))
