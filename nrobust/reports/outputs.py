"""Output directories: checked before any computation, written atomically, listed in a manifest.

Every command that writes a directory (``nrobust analyze``, ``paper``, ``sweep``) goes
through :class:`RunOutputs`:

1. **Checked first.** :func:`check_output_dir` creates the directory (and its parents) and
   writes and removes a probe file in it, so an unwritable place (``/proc/x``, a path
   under an existing file, a read-only mount) is a :class:`~nrobust.errors.ParameterError`
   before anything is computed.
2. **Staged.** The run writes its files into a hidden staging directory inside the output
   directory (same file system), by any means: :meth:`RunOutputs.write_text`,
   :meth:`RunOutputs.write_bytes`, :meth:`RunOutputs.savefig`, or a writer given
   :attr:`RunOutputs.staging` as its directory. A run that fails or is interrupted leaves
   the previous outputs untouched and its staging directory removed.
3. **Committed as a set.** :meth:`RunOutputs.commit` moves every staged file into place
   with ``os.replace`` (atomic per file), removes the files of the previous run that this
   run did not produce again (only files listed in the previous manifest), and writes
   ``manifest.json`` last, atomically: the run's files with their sizes and SHA-256, the
   nrobust version, the command and the time. A file whose size or SHA-256 disagrees with
   the manifest was not written by the run the manifest describes. The staging
   directory of a run killed outright (``SIGKILL``) is removed by the next commit.

Files a run appends to while it computes (the result journal of a sweep) live in the
output directory itself and are listed with :meth:`RunOutputs.keep`.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import shutil
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType
from typing import TYPE_CHECKING, Any

from .._atomic import atomic_write
from .._json import fields_dict
from .._version import __version__
from ..errors import ParameterError

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["MANIFEST", "Manifest", "RunOutputs", "atomic_write", "check_output_dir", "read_manifest"]

#: Name of the manifest in an output directory.
MANIFEST = "manifest.json"
_STAGING_PREFIX = ".nrobust-staging-"


def check_output_dir(path: str | os.PathLike[str], name: str = "out") -> Path:
    """Create ``path`` if needed and prove it is a writable directory.

    Parameters
    ----------
    path : path-like
        The output directory.
    name : str, optional
        The parameter named by the error (``"out"``: the ``-o`` option).

    Returns
    -------
    pathlib.Path
        The directory.

    Raises
    ------
    ParameterError
        Naming ``name``, when ``path`` is an existing file, lies under a file, cannot be
        created, or does not accept a new file.
    """
    out = Path(path)
    requirement = "a directory that can be created and written"
    if out.exists() and not out.is_dir():
        raise ParameterError(name, f"{requirement}; it is an existing file", str(out))
    try:
        out.mkdir(parents=True, exist_ok=True)
        fd, probe = tempfile.mkstemp(prefix=".nrobust-probe-", dir=out)
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        raise ParameterError(name, f"{requirement} ({exc.strerror or exc})", str(out)) from None
    return out


@dataclass(frozen=True)
class Manifest:
    """The files of one run in an output directory (``manifest.json``).

    Attributes
    ----------
    command : str
        What wrote them (``"analyze"``, ``"paper"``, ``"sweep"``).
    version : str
        The nrobust version.
    created : str
        UTC time of the commit, ISO 8601.
    files : tuple of dict
        ``{"path", "size", "sha256"}`` per file, ``path`` relative to the directory,
        ``/``-separated, sorted.
    """

    command: str
    version: str
    created: str
    files: tuple[dict[str, Any], ...]

    @property
    def paths(self) -> tuple[str, ...]:
        """The relative paths of the files."""
        return tuple(f["path"] for f in self.files)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict (the content of ``manifest.json``)."""
        return fields_dict(self)


def read_manifest(directory: str | os.PathLike[str]) -> Manifest | None:
    """The manifest of ``directory``, or None when it has none (or an unreadable one)."""
    try:
        data = json.loads((Path(directory) / MANIFEST).read_text(encoding="utf-8"))
        files = tuple(
            {"path": str(f["path"]), "size": int(f["size"]), "sha256": str(f["sha256"])} for f in data["files"]
        )
        return Manifest(str(data["command"]), str(data["version"]), str(data["created"]), files)
    except (OSError, ValueError, KeyError, TypeError):
        return None


def _sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with path.open("rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def _inside(directory: Path, relative: str) -> Path | None:
    """``directory / relative`` when it stays inside ``directory`` (a manifest is data, not trusted)."""
    target = (directory / relative).resolve()
    return target if target.is_relative_to(directory.resolve()) and target != directory.resolve() else None


class RunOutputs:
    """The files of one run in an output directory: checked first, staged, committed as a set.

    Parameters
    ----------
    directory : path-like
        The output directory; checked by :func:`check_output_dir` at construction.
    command : str
        Recorded in the manifest.

    Notes
    -----
    Use as a context manager: a normal exit commits (unless :meth:`commit` was called),
    an exception discards the staged files and leaves the directory as it was.
    """

    def __init__(self, directory: str | os.PathLike[str], command: str) -> None:
        self.directory = check_output_dir(directory)
        self.command = command
        self._staging: Path | None = None
        self._kept: list[str] = []
        self._done = False

    @property
    def staging(self) -> Path:
        """The staging directory (created on first use); write the run's files under it."""
        if self._done:
            raise ParameterError("outputs", "not yet committed or discarded (a run's files are staged once)")
        if self._staging is None:
            self._staging = Path(tempfile.mkdtemp(prefix=_STAGING_PREFIX, dir=self.directory))
        return self._staging

    def path(self, name: str) -> Path:
        """Where to stage the file ``name`` (a path relative to the output directory)."""
        target = self.staging / name
        target.parent.mkdir(parents=True, exist_ok=True)
        return target

    def final(self, staged: Any) -> Any:
        """Where staged files are committed to: a staged path becomes its path in the output
        directory, in tuples, lists and dataclasses too (e.g. the paths a writer returned)."""
        if isinstance(staged, Path) and staged.is_relative_to(self.staging):
            return self.directory / staged.relative_to(self.staging)
        if isinstance(staged, (tuple, list)):
            return type(staged)(self.final(v) for v in staged)
        if dataclasses.is_dataclass(staged) and not isinstance(staged, type):
            changes = {f.name: self.final(getattr(staged, f.name)) for f in dataclasses.fields(staged) if f.init}
            return dataclasses.replace(staged, **changes)
        return staged

    def write_text(self, name: str, text: str) -> Path:
        """Stage a UTF-8 text file; returns its final path."""
        self.path(name).write_text(text, encoding="utf-8")
        return self.directory / name

    def write_bytes(self, name: str, data: bytes) -> Path:
        """Stage a binary file; returns its final path."""
        self.path(name).write_bytes(data)
        return self.directory / name

    def savefig(self, name: str, fig: Figure, **kwargs: Any) -> Path:
        """Stage ``fig.savefig(...)``; returns the final path."""
        fig.savefig(self.path(name), **kwargs)
        return self.directory / name

    def keep(self, name: str) -> Path:
        """List a file the run wrote in place (e.g. an appended journal) in the manifest."""
        if not (self.directory / name).is_file():
            raise ParameterError("name", "an existing file of the output directory", name)
        self._kept.append(name)
        return self.directory / name

    def commit(self) -> Manifest:
        """Move the staged files into place, drop the previous run's leftovers, write the manifest."""
        if self._done:
            raise ParameterError("outputs", "committed once")
        previous = read_manifest(self.directory)
        staged = [] if self._staging is None else sorted(p for p in self._staging.rglob("*") if p.is_file())
        produced = {p.relative_to(self.staging).as_posix() for p in staged} | set(self._kept)
        for src in staged:
            dst = self.directory / src.relative_to(self.staging)
            dst.parent.mkdir(parents=True, exist_ok=True)
            os.replace(src, dst)
        if previous is not None:
            for rel in previous.paths:
                target = _inside(self.directory, rel)
                if rel not in produced and rel != MANIFEST and target is not None and target.is_file():
                    target.unlink()
        files = tuple(
            {"path": rel, "size": (self.directory / rel).stat().st_size, "sha256": _sha256(self.directory / rel)}
            for rel in sorted(produced)
        )
        created = time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())
        manifest = Manifest(self.command, __version__, created, files)
        with atomic_write(self.directory / MANIFEST) as fh:
            json.dump(manifest.to_dict(), fh, indent=2, allow_nan=False)
        self.discard()
        for leftover in self.directory.glob(f"{_STAGING_PREFIX}*"):  # of runs killed before they could clean up
            shutil.rmtree(leftover, ignore_errors=True)
        return manifest

    def discard(self) -> None:
        """Remove the staging directory and what it holds; the output directory is left as it was."""
        if self._staging is not None:
            shutil.rmtree(self._staging, ignore_errors=True)
        self._staging = None
        self._done = True

    def __enter__(self) -> RunOutputs:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        if exc_type is not None:
            self.discard()
        elif not self._done:
            self.commit()
