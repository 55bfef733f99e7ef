"""The exception types the CLI turns into one line and an exit code; nothing else catches
them.

:class:`UserError`: a mistake a user can make (bad file, bad config, bad flag): exit code 2,
which the systemd unit does not restart. :class:`Unavailable`: something that may come back
by itself (a serial device unplugged or held by another program): exit code
:data:`EXIT_UNAVAILABLE` (75, EX_TEMPFAIL of sysexits.h), which the unit restarts.
"""

#: Exit code of :class:`Unavailable` (sysexits.h EX_TEMPFAIL: try again later).
EXIT_UNAVAILABLE = 75


class UserError(Exception):
    """A problem with the user's input, explained in one sentence."""


class Unavailable(Exception):
    """A resource that is missing or busy now and may come back (the message is one line)."""
