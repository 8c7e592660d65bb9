"""Files that are whole or absent, and known to be intact: atomic writes, writer locks,
whole-file checksums and the clean-up of temporaries left by dead writers.

Every file of the result store is written by :func:`write_atomically`:

1. a lock file ``.<name>.<random>.lock`` is created and held (``flock``) by the writer;
2. the data go to ``.<name>.<random>.tmp`` beside it, which is flushed and fsynced;
3. for checksummed files the BLAKE2b digest of those bytes is written to ``<name>.b2``;
4. the temporary takes the final name (``os.replace``) and the lock file is removed.

A reader thus never sees a half-written file under a final name. A temporary whose lock
is still held belongs to a live writer, whatever the clocks say; :func:`remove_stale_temporaries`
removes only those whose writer has gone (lock free or absent). The lock is a separate
file because HDF5 takes its own ``flock`` on the file it writes.

A checksummed file whose bytes no longer match its ``.b2`` (a disk fault, a bad copy, an
overwrite in place) raises :class:`DamagedFile` in :func:`verify`: it is to be treated as
missing, never served. The digest is written before the file takes its name, so a crash
between the two leaves a mismatch (found) and never an unchecked file.
"""
from __future__ import annotations

import fcntl
import hashlib
import logging
import os
import tempfile
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

from .bounded import BoundedMemo

logger = logging.getLogger(__name__)

TMP_SUFFIX = ".tmp"
LOCK_SUFFIX = ".lock"
CHECKSUM_SUFFIX = ".b2"
_CHUNK = 1 << 20

#: Files verified by this process: path -> (inode, size, mtime ns, ctime ns) of the version
#: that matched its digest. Any rewrite changes the key (ctime cannot be set back), so an
#: unchanged key needs no second read. The most recent :data:`VERIFIED_MEMO` files (bounded:
#: a service meets every file of its store).
VERIFIED_MEMO = 4096
_VERIFIED: BoundedMemo[str, tuple[int, int, int, int]] = BoundedMemo(VERIFIED_MEMO)


class DamagedFile(Exception):
    """A stored file whose bytes do not match the checksum written with it; ``path`` is the file."""

    def __init__(self, message: str, path: Path | str | None = None):
        super().__init__(message)
        self.path = None if path is None else Path(path)


def digest(path: Path | str) -> str:
    """BLAKE2b-128 of the bytes of ``path``, in hex."""
    h = hashlib.blake2b(digest_size=16)
    with open(path, "rb") as fh:
        while chunk := fh.read(_CHUNK):
            h.update(chunk)
    return h.hexdigest()


def checksum_path(path: Path | str) -> Path:
    """Where the checksum of ``path`` is kept: ``<path>.b2``."""
    path = Path(path)
    return path.with_name(path.name + CHECKSUM_SUFFIX)


def _key(stat: os.stat_result) -> tuple[int, int, int, int]:
    return (stat.st_ino, stat.st_size, stat.st_mtime_ns, stat.st_ctime_ns)


def verify(path: Path | str, *, without_checksum: Callable[[Path], bool] | None = None) -> None:
    """Check ``path`` against its checksum (one read per version of the file).

    A file without a checksum is checked by ``without_checksum(path)`` (a check of its own
    content: True when it is sound, False when it cannot be told, :class:`DamagedFile` when it
    is damaged); a sound one, or any one when no such check is given (written before checksums
    existed), is adopted: its digest is recorded now (best effort on a read-only store).

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    DamagedFile
        If its bytes do not match the recorded digest.
    """
    path = Path(path)
    key = _key(path.stat())
    if _VERIFIED.get(str(path)) == key:
        return
    actual = digest(path)
    try:
        expected = checksum_path(path).read_text().strip()
    except FileNotFoundError:
        if without_checksum is not None and not without_checksum(path):
            raise DamagedFile(f"{path.name} has no checksum and cannot be verified", path) from None
        try:
            write_atomically(checksum_path(path), lambda tmp: tmp.write_text(actual + "\n"))
        except OSError:
            pass
        expected = actual
    if actual != expected:
        _VERIFIED.pop(str(path), None)
        raise DamagedFile(f"{path.name} does not match its checksum (damaged after it was written)", path)
    if _key(path.stat()) == key:  # unchanged while it was read
        _VERIFIED[str(path)] = key


def unverifiable(path: Path) -> bool:
    """For :func:`verify`: a file that cannot be checked without its checksum file (a cache,
    built again rather than adopted when its checksum is gone)."""
    return False


def remove_checksum(path: Path | str) -> None:
    """Drop the checksum of a removed file."""
    checksum_path(path).unlink(missing_ok=True)
    _VERIFIED.pop(str(path), None)


def _held_lock(folder: Path, prefix: str) -> tuple[int, Path]:
    """A new lock file in ``folder``, created and locked by this process (fd, path)."""
    while True:
        fd, name = tempfile.mkstemp(prefix=prefix, suffix=LOCK_SUFFIX, dir=folder)
        fcntl.flock(fd, fcntl.LOCK_EX)
        try:
            if os.stat(name).st_ino == os.fstat(fd).st_ino:
                return fd, Path(name)
        except FileNotFoundError:
            pass
        os.close(fd)  # a clean-up took the file between its creation and our lock: again


def write_atomically(target: Path, write: Callable[[Path], object], *, durable: bool = True,
                     checksum: bool = False) -> None:
    """Call ``write(tmp)`` on a temporary file next to ``target``, then rename it into place.

    The temporary file is flushed and fsynced before ``os.replace`` (unless not
    ``durable``: for caches that detect their own damage); with ``checksum`` its digest is
    recorded in ``<target>.b2`` first (see :func:`verify`). If ``write`` raises, the
    temporary is removed and nothing appears under ``target``. The writer holds a lock
    file for the whole write (see the module's text).
    """
    target = Path(target)
    target.parent.mkdir(parents=True, exist_ok=True)
    lock_fd, lock = _held_lock(target.parent, f".{target.name}.")
    tmp = lock.with_name(lock.name[:-len(LOCK_SUFFIX)] + TMP_SUFFIX)
    try:
        os.close(os.open(tmp, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o600))
        try:
            write(tmp)
            if durable:
                with open(tmp, "rb+") as fh:  # the writer closed it; make its bytes durable
                    fh.flush()
                    os.fsync(fh.fileno())
            os.chmod(tmp, 0o644)
            if checksum:
                text = digest(tmp) + "\n"
                write_atomically(checksum_path(target), lambda t: t.write_text(text), durable=durable)
            os.replace(tmp, target)
        except BaseException:
            tmp.unlink(missing_ok=True)
            raise
    finally:
        lock.unlink(missing_ok=True)
        os.close(lock_fd)
    if durable:
        _fsync_dir(target.parent)


def _fsync_dir(folder: Path) -> None:
    """Make a rename durable (best effort: not every file system allows it)."""
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def remove_stale_temporaries(root: Path | str) -> int:
    """Remove the temporaries (and lock files) of writers that have gone, anywhere under
    ``root``; return how many temporaries went. A temporary whose lock is held is a live
    write and stays, however old it looks."""
    removed = 0
    for folder, _, names in os.walk(root):
        folder_path = Path(folder)
        names = set(names)
        for name in sorted(n for n in names if n.endswith(TMP_SUFFIX) and n.startswith(".")):
            lock = folder_path / (name[:-len(TMP_SUFFIX)] + LOCK_SUFFIX)
            with _lock_if_free(lock) as free:
                if free and _unlink(folder_path / name):
                    _unlink(lock)
                    removed += 1
        for name in (n for n in names if n.endswith(LOCK_SUFFIX) and n.startswith(".")):
            if name[:-len(LOCK_SUFFIX)] + TMP_SUFFIX in names:
                continue
            lock = folder_path / name
            with _lock_if_free(lock) as free:  # a writer that died before or after its temporary
                if free and lock.exists():
                    _unlink(lock)
    return removed


def _unlink(path: Path) -> bool:
    """Remove ``path`` if there; False when the store refuses (read-only), which is logged."""
    try:
        path.unlink(missing_ok=True)
        return True
    except OSError as exc:
        logger.warning("could not remove %s: %s", path.name, exc)
        return False


@contextmanager
def _lock_if_free(lock: Path) -> Iterator[bool]:
    """True when ``lock`` is absent or could be locked now (its writer has gone); the lock is
    held inside the block, so removing it there is safe."""
    try:
        fd = os.open(lock, os.O_RDONLY)
    except FileNotFoundError:
        yield True
        return
    except OSError:
        yield False
        return
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            yield False
        else:
            yield True
    finally:
        os.close(fd)


def can_write(folder: Path | str) -> bool:
    """Whether a file can be made in ``folder`` (made if missing): False on a read-only mount."""
    try:
        Path(folder).mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=folder, prefix=".probe-"):
            return True
    except OSError:
        return False
