"""Replacing a folder atomically: a reader of the path sees the old folder or the new one,
never none and never a mix (``emit``'s target folders, ``build``'s cache folders).

Linux: ``renameat2(..., RENAME_EXCHANGE)`` (kernel >= 3.15; ext4, xfs, btrfs, tmpfs, overlayfs)
through ctypes on the C library. Elsewhere, or on a filesystem without the exchange, two
renames: the folder is briefly absent (kept only as a fallback).

Writers of one parent folder serialise the last step (check what is there, then place or swap)
with ``locked`` (an advisory lock on the parent folder itself: nothing is left behind), so the
check and the rename are one compare-and-swap; ``place_dir`` never replaces what appeared
meanwhile. A write that fails for lack of space or permission raises ``WriteError``: one line
naming the path and the fix.
"""
from __future__ import annotations

import ctypes
import errno
import fcntl
import os
import tempfile
from contextlib import contextmanager
from functools import lru_cache
from pathlib import Path

_AT_FDCWD = -100
_RENAME_NOREPLACE = 1
_RENAME_EXCHANGE = 2

# errno -> what the user does about it (WriteError)
_FIXES = {errno.ENOSPC: "free space on its filesystem", errno.EDQUOT: "free space within your quota",
          errno.EACCES: "make it writable", errno.EPERM: "make it writable",
          errno.EROFS: "it is on a read-only filesystem", errno.ENAMETOOLONG: "use a shorter name"}


class WriteError(OSError):
    """A file or folder could not be written (no space, no permission, a name too long): the
    message names the path and the fix; nothing half-written is left."""


def write_error(exc, path, elsewhere):
    """The WriteError of the OSError ``exc`` raised while writing ``path``; ``elsewhere`` says how
    to write to another place instead (e.g. "or choose another --out")."""
    fix = _FIXES.get(exc.errno, "check the path")
    return WriteError(f"cannot write {path}: {exc.strerror or exc}; {fix}, {elsewhere}")


@contextmanager
def locked(folder):
    """Hold an exclusive advisory lock (flock) on the directory ``folder`` for the with-block:
    the writers of one parent folder take turns (no lock file is left behind). A filesystem
    without locks (some network ones) goes unlocked: ``place_dir`` still never overwrites."""
    fd = os.open(folder, os.O_RDONLY | os.O_DIRECTORY)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX)
        except OSError as e:
            if e.errno not in (errno.ENOLCK, errno.EINVAL, errno.EBADF, errno.EOPNOTSUPP):
                raise
        yield
    finally:
        os.close(fd)          # releases the lock


def place_dir(src, dst):
    """Rename the folder ``src`` to ``dst`` only if nothing is at ``dst`` (FileExistsError
    otherwise): ``renameat2(RENAME_NOREPLACE)``, else a check then a rename (hold ``locked``
    on the parent to make that one step for the writers that lock it too)."""
    f = _renameat2()
    if f is not None:
        if f(_AT_FDCWD, os.fsencode(src), _AT_FDCWD, os.fsencode(dst), _RENAME_NOREPLACE) == 0:
            return
        code = ctypes.get_errno()
        if code not in (errno.ENOSYS, errno.EINVAL):
            raise OSError(code, os.strerror(code), str(dst))
    if os.path.lexists(dst):
        raise FileExistsError(errno.EEXIST, os.strerror(errno.EEXIST), str(dst))
    os.rename(src, dst)


@lru_cache(maxsize=1)
def _renameat2():
    try:
        f = ctypes.CDLL(None, use_errno=True).renameat2
    except (OSError, AttributeError):
        return None
    f.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_uint]
    f.restype = ctypes.c_int
    return f


def exchange(a, b):
    """Swap the paths ``a`` and ``b`` (both must exist) in one step; OSError when impossible
    (ENOSYS: no renameat2; EINVAL: the filesystem has no exchange)."""
    f = _renameat2()
    if f is None:
        raise OSError(errno.ENOSYS, "renameat2 is not available", str(a))
    if f(_AT_FDCWD, os.fsencode(a), _AT_FDCWD, os.fsencode(b), _RENAME_EXCHANGE) != 0:
        code = ctypes.get_errno()
        raise OSError(code, os.strerror(code), str(a), None, str(b))


def replace_dir(src, dst):
    """Move the folder ``src`` to ``dst``, replacing a folder there in one step.

    Returns
    -------
    Path or None
        Where the replaced folder now is (for the caller to delete), None if ``dst`` was free.
    """
    try:
        os.rename(src, dst)
        return None
    except OSError as e:
        if e.errno not in (errno.ENOTEMPTY, errno.EEXIST):
            raise
    try:
        exchange(src, dst)
        return Path(src)
    except OSError as e:
        if e.errno not in (errno.ENOSYS, errno.EINVAL):
            raise
    old = Path(tempfile.mkdtemp(prefix=".old.", dir=Path(dst).parent))
    os.rename(dst, old / "old")
    os.rename(src, dst)
    return old
