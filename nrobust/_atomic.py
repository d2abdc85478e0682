"""One file written atomically: a temporary file beside it, then ``os.replace``.

Used by every writer of nrobust (sweep tables and journals, manifests); the set of a
run's files is the job of :mod:`nrobust.reports.outputs`.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager, suppress
from pathlib import Path
from typing import IO, Any

from .errors import ParameterError

__all__ = ["atomic_write"]


def _umask() -> int:
    """The process's file mode creation mask (read by setting it and setting it back)."""
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


@contextmanager
def atomic_write(path: str | os.PathLike[str], mode: str = "w") -> Iterator[IO[Any]]:
    """Open a temporary file beside ``path``; on success it replaces ``path`` in one step.

    A reader sees the old file or the complete new one, never a part; on an exception the
    temporary file is removed and ``path`` is unchanged. ``mode`` is ``"w"`` (UTF-8 text)
    or ``"wb"``.
    """
    if mode not in ("w", "wb"):
        raise ParameterError("mode", "'w' or 'wb'", mode)
    target = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
    try:
        os.chmod(tmp, 0o666 & ~_umask())  # the permissions of a file opened for writing, not mkstemp's 0600
        fh: IO[Any] = open(fd, "w", encoding="utf-8", newline="") if mode == "w" else open(fd, "wb")
        with fh:
            yield fh
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, target)
    except BaseException:
        with suppress(OSError):
            os.unlink(tmp)
        raise
