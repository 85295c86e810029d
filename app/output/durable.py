"""What c2n writes reaches the disk, not only the system's cache, before it is put in place.

A rename is atomic for a crash or a kill, whose process dies but whose system goes on writing
its cache out. A power cut (a car's ignition, a laptop's battery) loses that cache: a file
renamed into place before its content was synced can come back empty or short, the older one
already gone. So a temporary is synced before the rename that puts it in place, and the folder
after it (the new name is an entry of the folder); a growing recording is synced every second
(``PeriodicSync``). A file system that cannot sync (``EINVAL``: some network and FUSE mounts)
keeps what it keeps; a disk that fails to (``EIO``, a full disk's ``ENOSPC`` on NFS) is an error.
On macOS ``fsync`` leaves the data in the drive's own cache, which a cut loses too: there a sync is
``F_FULLFSYNC`` (fcntl(2): the drive is asked to write its cache out), ``fsync`` where the file
system has no such call.
"""

import errno
import os
import sys
import threading
from collections.abc import Sequence
from pathlib import Path

# fcntl(2)'s F_FULLFSYNC: macOS's sync through the drive's cache (Linux's fsync already asks the
# drive to write its cache out; Windows's FlushFileBuffers does)
if sys.platform == "darwin":
    import fcntl

    _FULL_SYNC: int | None = fcntl.F_FULLFSYNC
else:
    _FULL_SYNC = None

# fsync(2) on a file system or an object that has no sync: nothing more can be done there
_CANNOT_SYNC = frozenset({errno.EINVAL, errno.ENOTSUP, errno.EOPNOTSUPP, errno.EROFS, errno.EBADF})


def synced(path: Path) -> None:
    """``path``'s content on the disk: a file's data, a folder's entries (names made, renamed or
    removed in it). A folder c2n may write in but not list (mode 0300) cannot be opened to sync:
    its entries are left to the system, as Windows's are (NTFS journals them itself)."""
    folder = path.is_dir()
    if folder and os.name == "nt":
        return
    try:
        fd = os.open(path, os.O_RDONLY | (getattr(os, "O_DIRECTORY", 0) if folder else 0))
    except PermissionError:
        if folder:
            return
        raise
    try:
        _sync(fd)
    finally:
        os.close(fd)


def synced_tree(folder: Path) -> None:
    """Every file and folder under ``folder``, and ``folder`` itself, on the disk."""
    for root, folders, files in os.walk(folder, topdown=False):
        here = Path(root)
        for name in files:
            if not (here / name).is_symlink():
                synced(here / name)
        for name in folders:
            if not (here / name).is_symlink():
                synced(here / name)
    synced(folder)


def _sync(fd: int) -> None:
    try:
        _to_the_disk(fd)
    except OSError as error:
        if error.errno not in _CANNOT_SYNC:
            raise


def _to_the_disk(fd: int) -> None:
    """fsync(2); on macOS F_FULLFSYNC (SQLite's ``fullfsync``), and fsync where a file system
    refuses that (SMB, some FAT drivers)."""
    if _FULL_SYNC is not None:
        import fcntl

        try:
            fcntl.fcntl(fd, _FULL_SYNC)
            return
        except OSError:
            pass
    os.fsync(fd)


class PeriodicSync:
    """Files a session keeps growing (the raw log, the events table), synced every ``every_s``
    seconds by a thread of their own: a power cut loses at most that much of what was written,
    and a slow disk (a USB stick's sync can take a second) never holds up the bus's reader.
    ``error``: the first sync the disk refused; syncing stops there. ``close`` syncs once more
    (after the writers closed: this holds its own descriptors) and stops the thread."""

    def __init__(self, paths: Sequence[Path], every_s: float = 1.0) -> None:
        self.every_s = every_s
        self.error: OSError | None = None
        self._fds = [os.open(path, os.O_RDONLY) for path in paths]
        self._stop = threading.Event()
        self._lock = threading.Lock()  # close's last sync after the thread's, never beside it
        self._thread = threading.Thread(target=self._run, name="c2n-sync", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.wait(self.every_s):
            self.sync()

    def sync(self) -> None:
        with self._lock:
            for fd in self._fds:
                if self.error is not None:
                    return
                try:
                    _sync(fd)
                except OSError as error:
                    self.error = error

    def close(self) -> None:
        """The last sync and the thread stopped (once; again is nothing)."""
        if self._stop.is_set():
            return
        self._stop.set()
        self._thread.join()
        try:
            self.sync()
        finally:
            for fd in self._fds:
                os.close(fd)
