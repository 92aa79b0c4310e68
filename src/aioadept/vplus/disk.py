"""V+ disk files for the emulator, confined to one folder: ``ATTACH (lun, 4) "DISK"``, ``FOPENR``, ``FOPENW``,
``FOPENA``, ``FOPEND``, ``READ``/``WRITE``/``FCLOSE``/``DETACH`` on a disk LUN, ``FDELETE``, ``IOSTAT``.

Semantics from the V+ Language User's Guide v17, "Disk I/O" (pp. 214-217): a disk LUN is attached with
``ATTACH (dlun, 4) "DISK"``; each program task has its own disk LUNs and one file open on each; FOPENR opens for
read only (an error if the file does not exist), FOPENW for write (an error if it exists, else a new file),
FOPENA for append (created if missing, never an error), FOPEND a directory for reading, a record per READ; while
a file is open for write or append no other task can open it; I/O errors are reported by IOSTAT, never stop the
program. Records are sequential, variable length, each ended by CR LF (WRITE adds it unless ``/S``).

The disk is a folder of the host that the user names (``Emulator(disk_dir=...)``, ``aioadept sim --vplus ...
--disk DIR``; a new temporary folder by default). A file specification ``[unit:][\\path\\]name.ext`` names a file
in it: the unit letter is ignored (one disk), ``\\`` (and ``/`` inside a name) separate folders, a leading ``\\``
starts at the folder itself (V+'s absolute path on the unit). A name with ``..``, a host absolute path
(``/etc/passwd``), or a symbolic link that leads out of the folder is refused with IOSTAT ``*Invalid file name*`` and no
file is touched. Error numbers are in :mod:`aioadept.vplus.errors` (UNCONFIRMED, as noted there).

A file name is 1 to 8 characters with an extension of 0 to 3 (p. 216); a longer one is ``*Invalid file name*``.

Choices where the guide is silent (docs/vplus.md): a record longer than 128 characters is handed over 128 at a
time; a directory record is ``name.ext size`` (UNCONFIRMED format); ``FOPEN_`` on a LUN that has a file open is
an error (close it first).
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path
from typing import Any

from aioadept.vplus import errors as E

_READ_MAX = 128


class DiskFolder:
    """The emulated disk: a host folder (created lazily as a temporary folder when none is named)."""

    def __init__(self, root: str | os.PathLike | None = None) -> None:
        self._given = None if root is None else Path(root)
        self._tmp: tempfile.TemporaryDirectory | None = None
        self.writers: dict[Path, Any] = {}     # files open for write/append: path -> the DiskLun holding it

    @property
    def root(self) -> Path:
        if self._given is not None:
            self._given.mkdir(parents=True, exist_ok=True)
            return self._given.resolve()
        if self._tmp is None:
            self._tmp = tempfile.TemporaryDirectory(prefix="vplus-disk-")
        return Path(self._tmp.name).resolve()

    def path(self, spec: str) -> Path | None:
        """The host path of a V+ file specification inside the folder, or None if it would leave it."""
        spec = spec.strip()
        if len(spec) >= 2 and spec[1] == ":" and spec[0].isalpha():
            spec = spec[2:]                      # the disk unit (A:, C:, D:): one disk here
        if not spec or "\0" in spec or spec.startswith("/"):
            return None                          # a host absolute path (V+ paths use \\): refused
        parts = [p for p in spec.replace("\\", "/").split("/") if p not in ("", ".")]
        if any(p == ".." for p in parts):
            return None
        root = self.root
        if not parts:
            return root                          # "\\": the folder itself (a directory read, FOPEND)
        target = root.joinpath(*parts)
        try:
            real = target.resolve()             # follows symbolic links: one leading out is refused
        except (OSError, RuntimeError):
            return None
        if real != root and root not in real.parents:
            return None
        return real


class DiskLun:
    """One attached disk logical unit of a task: at most one file (or directory listing) open on it."""

    def __init__(self, rt: Any, task: Any, lun: int) -> None:
        self.rt, self.task, self.lun = rt, task, lun
        self.file: Any = None
        self.path: Path | None = None
        self.mode = ""                           # "R", "W", "A", "D"
        self.listing: list[str] = []
        self.rest = ""                           # the part of a long record not yet read

    @property
    def folder(self) -> DiskFolder:
        d = getattr(self.rt, "disk", None)
        if d is None:
            d = self.rt.disk = DiskFolder()
        return d

    def open(self, how: str, spec: str) -> int:
        """FOPENR/W/A/D: IOSTAT of the open (1 or a negative error)."""
        if self.file is not None or self.mode == "D":
            return E.FILE_IN_USE
        path = self.folder.path(spec.split()[0] if spec.split() else "")
        if path is None or (how != "D" and not _dos_name(path.name)):
            return E.ILLEGAL_FILE_NAME
        if how == "D":
            target = path if path.is_dir() else path.parent
            if not target.is_dir():
                return E.NONEXISTENT_FILE
            self.listing = [f"{p.name} {p.stat().st_size}" for p in sorted(target.iterdir()) if p.is_file()]
            self.mode, self.path = "D", target
            return 1
        if path in self.folder.writers or (how != "R" and any(
                lun.path == path for lun in _open_luns(self.rt) if lun is not self)):
            return E.FILE_IN_USE
        try:
            if how == "R":
                if not path.is_file():
                    return E.NONEXISTENT_FILE
                self.file = open(path, "rb")
            elif how == "W":
                if path.exists():
                    return E.FILE_EXISTS
                if not path.parent.is_dir():
                    return E.NONEXISTENT_FILE
                self.file = open(path, "xb")
            else:
                if path.exists() and not path.is_file():
                    return E.ILLEGAL_FILE_NAME
                if not path.parent.is_dir():
                    return E.NONEXISTENT_FILE
                self.file = open(path, "ab")
        except OSError:
            return E.DEVICE_ERROR
        self.mode, self.path, self.rest = how, path, ""
        if how in ("W", "A"):
            self.folder.writers[path] = self
        return 1

    def read(self) -> tuple[int, str]:
        """READ: (IOSTAT, the next record without its CR LF)."""
        if self.mode == "D":
            if not self.listing:
                return E.END_OF_FILE, ""
            return 1, self.listing.pop(0)
        if self.file is None or self.mode != "R":
            return E.NOT_OPEN, ""
        if self.rest:
            rec, self.rest = self.rest[:_READ_MAX], self.rest[_READ_MAX:]
            return 1, rec
        raw = self.file.readline()
        if not raw:
            return E.END_OF_FILE, ""
        text = raw.decode("latin-1").rstrip("\n").rstrip("\r")
        rec, self.rest = text[:_READ_MAX], text[_READ_MAX:]
        return 1, rec

    def write(self, text: str) -> int:
        if self.file is None or self.mode not in ("W", "A"):
            return E.NOT_OPEN
        try:
            self.file.write(text.encode("latin-1"))
            self.file.flush()
        except (OSError, UnicodeEncodeError):
            return E.DEVICE_ERROR
        return 1

    def close(self) -> int:
        if self.file is not None:
            self.file.close()
        if self.path is not None and self.folder.writers.get(self.path) is self:
            del self.folder.writers[self.path]
        self.file, self.path, self.mode, self.listing, self.rest = None, None, "", [], ""
        return 1

    def delete(self, spec: str) -> int:
        """FDELETE: remove a file of the folder (not one open for write anywhere)."""
        path = self.folder.path(spec.split()[0] if spec.split() else "")
        if path is None or not _dos_name(path.name):
            return E.ILLEGAL_FILE_NAME
        if path in self.folder.writers or any(lun.path == path for lun in _open_luns(self.rt)):
            return E.FILE_IN_USE
        if not path.is_file():
            return E.NONEXISTENT_FILE
        try:
            path.unlink()
        except OSError:
            return E.DEVICE_ERROR
        return 1


def _dos_name(name: str) -> bool:
    """A V+ file name: 1 to 8 characters, an extension of 0 to 3 (User's Guide v17 p. 216)."""
    base, dot, ext = name.partition(".")
    return 1 <= len(base) <= 8 and len(ext) <= 3 and "." not in ext


def _open_luns(rt: Any) -> list[DiskLun]:
    return [d for T in rt.tasks.values() for d in T.luns.values() if isinstance(d, DiskLun) and d.path is not None]


def open_file(T: Any, word: str, lun: Any, spec: str) -> None:
    """FOPENR, FOPENW, FOPENA, FOPEND, FDELETE (``word``) of the file ``spec`` on disk LUN ``lun``: IOSTAT."""
    n = int(lun)
    dev = T.luns.get(n)
    if not isinstance(dev, DiskLun):
        T.iostat[n] = E.NOT_ATTACHED
        return
    T.iostat[n] = dev.delete(spec) if word == "FDELETE" else dev.open(word[-1], spec)


def read(T: Any, dev: DiskLun, targets: tuple) -> None:
    """READ (dlun) $s, ...: the next record into the first target (the others get "")."""
    st, rec = dev.read()
    for i, (c, k) in enumerate(targets):
        c[k] = rec if i == 0 else ""
    T.iostat[dev.lun] = st


def write(T: Any, dev: DiskLun, text: str) -> None:
    """WRITE (dlun) ...: ``text`` is the rendered record with its line end (or without, after ``/S``)."""
    T.iostat[dev.lun] = dev.write(text)
