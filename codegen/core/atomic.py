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


# ------------------------------------------------------------------------------ output sets
MANIFEST = ".codegen-outputs.json"     # what the last set written into a folder holds (name -> size, mtime)


def check_writable(path, elsewhere, folder=False):
    """WriteError (naming ``path`` and the fix, then ``elsewhere``: how to write to another place)
    when ``path`` (a file, or a folder when ``folder``) cannot be written: the folder it goes in,
    or its nearest existing parent, refuses a file.
    Probed with an unnamed temporary file (nothing is left), so it holds for root and for
    read-only filesystems alike. Run before the work whose result goes there."""
    path = Path(path).absolute()
    where = path if folder else path.parent
    probe = where
    while not probe.exists():
        if probe.parent == probe:
            break
        probe = probe.parent
    if not probe.is_dir():
        raise WriteError(f"cannot write {path}: {probe} is not a folder; {elsewhere}")
    try:
        with tempfile.TemporaryFile(dir=probe):
            pass
    except OSError as e:
        fix = _FIXES.get(e.errno, "make it writable")
        raise WriteError(f"cannot write {path}: the folder {probe} takes no new file ({e.strerror or e}); "
                         f"{fix}, {elsewhere}") from None
    if not folder and path.exists() and not os.access(path, os.W_OK) and not os.access(where, os.W_OK):
        raise write_error(OSError(errno.EACCES, os.strerror(errno.EACCES)), path, elsewhere)


def check_not_input(outputs, inputs, elsewhere):
    """ValueError when a path of ``outputs`` is one of the ``inputs`` (resolved: the same file
    through another name or a link), before the run that would overwrite what it reads; the
    message ends with ``elsewhere`` (what to choose instead)."""
    seen = {}
    for p in inputs:
        if p is not None and Path(p).exists():
            seen[Path(p).resolve()] = p
    for out in outputs:
        r = Path(out).resolve()
        if r in seen:
            raise ValueError(f"{out}: this output is the input {seen[r]} (the run would overwrite what it "
                             f"reads); {elsewhere}")


def write_text(path, text, elsewhere):
    """``text`` into the file ``path`` through a temporary file in its folder, renamed into place
    (a reader sees the old file or the new one); WriteError naming the path and the fix, then
    ``elsewhere``. Returns the path."""
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
        try:
            with os.fdopen(fd, "w") as f:
                f.write(text)
            os.replace(tmp, path)
        except BaseException:
            os.unlink(tmp)
            raise
    except OSError as e:
        raise write_error(e, path, elsewhere) from None
    return path


@contextmanager
def held_signals(signums=None):
    """SIGINT and SIGTERM (or ``signums``) held back for the with-block and delivered after it (a
    Ctrl-C then interrupts after the block, never inside it). Only the main thread can hold them;
    elsewhere the block runs as it is."""
    import signal
    import threading
    signums = (signal.SIGINT, signal.SIGTERM) if signums is None else signums
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    caught, old = [], {}

    def note(signum, frame):
        caught.append(signum)
    for s in signums:
        old[s] = signal.signal(s, note)
    try:
        yield
    finally:
        for s, h in old.items():
            signal.signal(s, h)
        for s in dict.fromkeys(caught):
            os.kill(os.getpid(), s)


class OutputSet:
    """The files ``names`` a command writes into ``folder`` (created), as one set.

    Made before the work: refuses (WriteError) a folder that cannot be written, (ValueError) an
    output that is one of the ``inputs``, or a file of the set already there that the folder's
    manifest (``MANIFEST``: the name, size and mtime of each file of the last set) does not list
    as written by us (a user's file; ``ours``: the folder is a scratch folder of ours, replaced
    freely). ``writing()`` then gives a temporary folder beside them; on leaving it the files
    move into place under the folder's lock (two writers never mix their files) with SIGINT and
    SIGTERM held back, the manifest last: the folder holds the old set or the new one, never a
    cut file; an error or an interrupt before that leaves the old set and no temporary file.
    """

    def __init__(self, folder, names, inputs=(), elsewhere="choose another folder", ours=False):
        self.folder, self.names, self.elsewhere, self.ours = Path(folder), list(names), elsewhere, ours
        check_writable(self.folder, elsewhere, folder=True)
        check_not_input([self.folder / n for n in self.names], inputs, elsewhere)
        if self.folder.is_dir():
            with locked(self.folder):       # a set being placed meanwhile is seen whole
                self._foreign()

    def _manifest(self):
        import json
        try:
            return json.loads((self.folder / MANIFEST).read_text()).get("files", {})
        except (OSError, ValueError, AttributeError):
            return {}

    def _foreign(self):
        """ValueError naming a file of the set in the folder that the manifest does not list."""
        if self.ours:
            return
        listed = self._manifest()
        for name in self.names:
            p = self.folder / name
            if os.path.lexists(p):
                st = p.lstat()
                if listed.get(name) != [st.st_size, st.st_mtime_ns]:
                    raise ValueError(f"{p} exists and was not written by this command (the folder's "
                                     f"{MANIFEST} does not list it): it is not replaced; move it, or "
                                     f"{self.elsewhere}")

    def _record(self, tmp):
        """Write the manifest of the set's files now in the folder (through ``tmp``, a folder beside it)."""
        import json
        files = {}
        for name in self.names:
            p = self.folder / name
            if p.exists():
                st = p.stat()
                files[name] = [st.st_size, st.st_mtime_ns]
        (Path(tmp) / MANIFEST).write_text(json.dumps({"files": files}, indent=1) + "\n")
        os.replace(Path(tmp) / MANIFEST, self.folder / MANIFEST)

    def record(self):
        """List the set's files now in the folder as ours (a writer of its own placed them: the
        next run may replace them); WriteError when the manifest cannot be written."""
        try:
            with locked(self.folder):
                tmp = Path(tempfile.mkdtemp(prefix=".out.", dir=self.folder))
                try:
                    self._record(tmp)
                finally:
                    import shutil
                    shutil.rmtree(tmp, ignore_errors=True)
        except OSError as e:
            raise write_error(e, self.folder / MANIFEST, self.elsewhere) from None

    @contextmanager
    def writing(self):
        """A temporary folder to write the set's files into; moved into place on success."""
        import shutil
        made = not self.folder.exists()
        try:
            self.folder.mkdir(parents=True, exist_ok=True)
            tmp = Path(tempfile.mkdtemp(prefix=".out.", dir=self.folder))
        except OSError as e:
            raise write_error(e, self.folder, self.elsewhere) from None
        try:
            yield tmp
            with held_signals():
                with locked(self.folder):
                    self._foreign()
                    for name in self.names:
                        if (tmp / name).exists():
                            os.replace(tmp / name, self.folder / name)
                    self._record(tmp)
        except OSError as e:
            if isinstance(e, WriteError):
                raise
            raise write_error(e, self.folder, self.elsewhere) from None
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
            if made:
                try:
                    self.folder.rmdir()        # only when nothing was placed in it
                except OSError:
                    pass
