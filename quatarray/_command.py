"""Ctrl-C while the ``quatarray`` command is still starting ends it quietly.

Imported first by ``quatarray/__init__.py``: NumPy and quatarray take a noticeable
moment to import, and Ctrl-C in that moment would print a ``KeyboardInterrupt``
traceback before `quatarray.cli.main` (which ends quietly with status 130) runs.
In the ``quatarray`` command (``quatarray ...`` or ``python -m quatarray ...``)
an interrupt that reaches the top level is therefore not printed; the process
still ends by SIGINT, as the shell expects.  Any other program importing
quatarray keeps Python's own behaviour.
"""

import os
import sys


def _is_command():
    argv = list(getattr(sys, "orig_argv", []))
    if "-m" in argv:
        return argv[argv.index("-m") + 1:argv.index("-m") + 2] == ["quatarray"]
    name = os.path.basename(sys.argv[0]) if sys.argv and sys.argv[0] else ""
    return os.path.splitext(name)[0] == "quatarray"


def _quiet_interrupt(kind, value, traceback, previous=sys.excepthook):
    if issubclass(kind, KeyboardInterrupt):
        return
    previous(kind, value, traceback)


if _is_command():
    sys.excepthook = _quiet_interrupt
