"""Errors that reach the user as one line and a non-zero exit (never a traceback): tdem's name
for :class:`thermal_kernel.errors.UserError`, whose home is below ``tdem`` and ``validation``
(both raise it; ``tdem`` imports ``validation``, never the reverse)."""
from thermal_kernel.errors import UserError

__all__ = ["UserError"]
