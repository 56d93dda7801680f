"""Errors that reach the user as one line and a non-zero exit (never a traceback)."""


class UserError(Exception):
    """Bad input or a failed external step; ``str(e)`` names the file, the field and what was
    expected."""
