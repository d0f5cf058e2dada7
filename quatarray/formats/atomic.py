"""Atomic writes: temporary files beside the targets, renamed onto them only when complete.

Shared by every format's writer, so a failed or interrupted write never leaves a
partial file at the name asked for.  `atomic_files` writes several files that
belong together (a ``.gltf`` and its ``.bin``): all of them are replaced, or
none.
"""

import contextlib
import errno
import os
import shutil
import tempfile

__all__ = ["atomic_write", "atomic_files"]

_NAME_MAX = 255   # bytes in a file name (ext4, XFS, APFS, tmpfs; NTFS's 255 UTF-16 units are never fewer)
_RANDOM = 8       # the characters mkstemp puts between its prefix and suffix


@contextlib.contextmanager
def _naming(path):
    """Raise an OSError from inside naming `path`, the file asked for, not a temporary one."""
    try:
        yield
    except OSError as exc:
        raise type(exc)(exc.errno, exc.strerror, path) from None


def _temporary(path, suffix):
    """mkstemp beside `path`, named ``.{name}.{random}{suffix}`` after `path`'s name, which is cut (at a
    character, so a UTF-8 name stays UTF-8) where the whole would not fit in a file name."""
    folder, name = os.path.split(os.path.abspath(path))
    room = _NAME_MAX - len(f"..{suffix}") - _RANDOM
    while len(os.fsencode(name)) > room:
        name = name[:-1]
    with _naming(path):
        return tempfile.mkstemp(dir=folder, prefix=f".{name}.", suffix=suffix)


def _backup(path):
    """A second name beside `path` for the file there, to put it back after it was replaced: a hard link
    (a copy where the file system has none).  None if there is no file."""
    if not os.path.lexists(path):
        return None
    fd, backup = _temporary(path, ".old")
    os.close(fd)
    try:
        with _naming(path):
            os.unlink(backup)   # link() needs a free name: mkstemp's, which no other file takes
            try:
                os.link(path, backup, follow_symlinks=False)
            except (OSError, NotImplementedError):   # FAT, some network shares; follow_symlinks on Windows
                shutil.copy2(path, backup, follow_symlinks=False)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(backup)
        raise
    return backup


def _sync_folder(folder):
    """The renames in `folder` on disk (POSIX: fsync of the directory; where a directory cannot be
    opened or synced, as on Windows, its file system orders the rename itself)."""
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


class _Staged:
    """The files of an `atomic_files` block: (temporary, path) of each file written, in order."""

    def __init__(self):
        self.files = []

    @contextlib.contextmanager
    def open(self, path, binary=False, newline="\n"):
        """A temporary file beside `path`, to be renamed onto it when the `atomic_files` block ends."""
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
                    f.flush()
                    os.fsync(f.fileno())   # on disk before it is renamed: a crash then leaves the old file or the new
            except OSError as exc:   # a full disk (errno 28) while writing or closing names no file: name it
                if exc.filename is not None or exc.errno is None:
                    raise
                raise type(exc)(exc.errno, exc.strerror, path) from None
        except BaseException:
            if fd is not None:
                os.close(fd)
            with contextlib.suppress(OSError):
                os.unlink(tmp)
            raise
        self.files.append((tmp, path))

    def discard(self):
        """Remove the temporaries that are still there (not renamed)."""
        for tmp, _ in self.files:
            with contextlib.suppress(OSError):
                os.unlink(tmp)

    def commit(self):
        """Rename every temporary onto its path in order; if one rename fails, undo those before it."""
        backups = []
        try:
            for _, path in self.files[:-1]:   # the last rename commits: nothing after it can fail
                backups.append(_backup(path))
            for tmp, path in self.files:
                with _naming(path):
                    os.replace(tmp, path)
            for folder in {os.path.dirname(os.path.abspath(path)) for _, path in self.files}:
                _sync_folder(folder)
        except BaseException:
            if self.files and os.path.lexists(self.files[-1][0]):   # not committed
                for i, ((tmp, path), backup) in enumerate(zip(self.files, backups)):
                    if os.path.lexists(tmp):
                        continue   # not renamed: nothing to undo
                    backups[i] = None   # put back now, or else kept beside `path`: the only copy of its old file
                    with contextlib.suppress(OSError):
                        if backup:
                            os.replace(backup, path)
                        else:
                            os.unlink(path)   # it did not exist
            raise
        finally:
            self.discard()
            for backup in filter(None, backups):
                with contextlib.suppress(OSError):
                    os.unlink(backup)


@contextlib.contextmanager
def atomic_files():
    """Write several files that are replaced together: all of them, or (on any failure) none.

    In ``with atomic_files() as files:``, ``files.open(path, binary=False,
    newline="\\n")`` opens each file as `atomic_write` does: a temporary file
    beside `path`.  When the block ends without an exception, the temporaries
    are renamed onto their paths in the order they were opened; the last
    rename commits.  Before the first, every file to be replaced but the last
    gets a second name beside it (a hard link, or a copy where the file
    system has no hard links), so that if a rename fails, those renamed
    before it are put back as they were (a file that did not exist is
    removed).  On any exception, including KeyboardInterrupt and the
    SystemExit the command line raises on SIGTERM, no temporary is left
    behind, nor a backup (unless putting it back failed: then it is the
    only copy of the old file), and every error names a path asked for.

    Examples
    --------
    >>> import os, tempfile
    >>> from quatarray.formats.atomic import atomic_files
    >>> folder = tempfile.TemporaryDirectory()
    >>> with atomic_files() as files:
    ...     for name in ("scene.bin", "scene.gltf"):
    ...         with files.open(os.path.join(folder.name, name)) as f:
    ...             _ = f.write(name)
    >>> sorted(os.listdir(folder.name))
    ['scene.bin', 'scene.gltf']
    """
    staged = _Staged()
    try:
        yield staged
    except BaseException:
        staged.discard()
        raise
    staged.commit()


@contextlib.contextmanager
def atomic_write(path, binary=False, newline="\n"):
    """Open a temporary file beside `path`; rename it to `path` only on success.

    An existing file's permission bits are kept; a new file gets the usual
    mode (``0o666`` less the umask).  Every error names `path`, never the
    temporary file; on any exception (including KeyboardInterrupt and the
    SystemExit the command line raises on SIGTERM) the temporary file is
    removed and `path` is left as it was.
    """
    with atomic_files() as files, files.open(path, binary, newline) as f:
        yield f
