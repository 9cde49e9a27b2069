"""Replacing a folder atomically: a reader of the path sees the old folder or the new one,
never none and never a mix (``emit``'s target folders, ``build``'s cache folders).

Linux: ``renameat2(..., RENAME_EXCHANGE)`` (kernel >= 3.15; ext4, xfs, btrfs, tmpfs, overlayfs)
through ctypes on the C library. Elsewhere, or on a filesystem without the exchange, two
renames: the folder is briefly absent (kept only as a fallback).
"""
from __future__ import annotations

import ctypes
import errno
import os
import tempfile
from functools import lru_cache
from pathlib import Path

_AT_FDCWD = -100
_RENAME_EXCHANGE = 2


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
