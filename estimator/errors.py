"""The one exception type for mistakes a user can make (bad file, bad config, bad flag).

The CLI prints its message as one line and exits with code 2; nothing else catches it.
"""


class UserError(Exception):
    """A problem with the user's input, explained in one sentence."""
