"""The exception types the CLI turns into one line and an exit code; nothing else catches
them.

:class:`UserError`: a mistake a user can make (bad file, bad config, bad flag): exit code 2,
which the systemd unit does not restart. :class:`Unavailable`: something that may come back
by itself (a serial device unplugged or held by another program): exit code
:data:`EXIT_UNAVAILABLE` (75, EX_TEMPFAIL of sysexits.h), which the unit restarts.
:func:`naming` words a log's error once a command goes on past it (replay, fleet).
"""

#: Exit code of :class:`Unavailable` (sysexits.h EX_TEMPFAIL: try again later).
EXIT_UNAVAILABLE = 75


class UserError(Exception):
    """A problem with the user's input, explained in one sentence."""


class Unavailable(Exception):
    """A resource that is missing or busy now and may come back (the message is one line)."""


def naming(path: object, message: str) -> str:
    """``message`` about the file ``path``, naming the path once: unchanged when it already
    names it (the readers' errors do), else after ``path:``."""
    return message if str(path) in message else f"{path}: {message}"
