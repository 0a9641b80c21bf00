"""The one error type for bad input from a user: the CLI prints its message, no traceback."""


class UserError(Exception):
    """Bad input (file, option, model) that the user can fix; the message says how."""
