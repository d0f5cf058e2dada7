"""Atomic writes: a temporary file beside the target, renamed onto it only when complete.

Shared by every format's writer, so a failed or interrupted write never leaves a
partial file at the name asked for.
"""

import contextlib
import errno
import os
import tempfile

__all__ = ["atomic_write"]

_NAME_MAX = 255   # bytes in a file name (ext4, XFS, APFS, tmpfs; NTFS's 255 UTF-16 units are never fewer)
_RANDOM = 8       # the characters mkstemp puts between its prefix and suffix


def _temporary(path, suffix):
    """mkstemp beside `path`, named ``.{name}.{random}{suffix}`` after `path`'s name, which is cut (at a
    character, so a UTF-8 name stays UTF-8) where the whole would not fit in a file name."""
    folder, name = os.path.split(os.path.abspath(path))
    room = _NAME_MAX - len(f"..{suffix}") - _RANDOM
    while len(os.fsencode(name)) > room:
        name = name[:-1]
    try:
        return tempfile.mkstemp(dir=folder, prefix=f".{name}.", suffix=suffix)
    except OSError as exc:  # name the file asked for, not the temporary one
        raise type(exc)(exc.errno, exc.strerror, path) from None


@contextlib.contextmanager
def atomic_write(path, binary=False, newline="\n"):
    """Open a temporary file beside `path`; rename it to `path` only on success.

    An existing file's permission bits are kept; a new file gets the usual
    mode (``0o666`` less the umask).  Every error names `path`, never the
    temporary file; on any exception (including KeyboardInterrupt and the
    SystemExit the command line raises on SIGTERM) the temporary file is
    removed and `path` is left as it was.
    """
    path = os.fspath(path)
    if os.path.isdir(path):
        raise IsADirectoryError(errno.EISDIR, os.strerror(errno.EISDIR), path)
    try:
        mode = os.stat(path).st_mode & 0o7777
    except OSError:
        mask = os.umask(0)
        os.umask(mask)
        mode = 0o666 & ~mask
    fd, tmp = _temporary(path, ".part")
    try:
        os.chmod(tmp, mode)  # mkstemp makes 0600
        try:
            with (os.fdopen(fd, "wb") if binary else
                  os.fdopen(fd, "w", encoding="utf-8", errors="surrogateescape", newline=newline)) as f:
                fd = None
                yield f
        except OSError as exc:   # a full disk (errno 28) while writing or closing names no file: name it
            if exc.filename is not None or exc.errno is None:
                raise
            raise type(exc)(exc.errno, exc.strerror, path) from None
        try:
            os.replace(tmp, path)
        except OSError as exc:
            raise type(exc)(exc.errno, exc.strerror, path) from None
    except BaseException:
        if fd is not None:
            os.close(fd)
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise
