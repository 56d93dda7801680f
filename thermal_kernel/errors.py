"""Errors that reach the user as one line, below every module that raises them.

:class:`SceneError`: raised by the scene reader (``scene.py``), the boundary kinds
(``boundaries/``), ``problem.py``, ``neighbours.py`` and ``calibrate.py``: its own module, so
that the boundary kinds need not import the scene reader that imports them.
:class:`UserError`: the base of the command line's and the validation cases' errors (``tdem``
imports ``validation``, never the reverse, so its home is below both).
"""


class SceneError(ValueError):
    """A bad scene file; ``str(e)`` is one line naming the file and the key."""


class UserError(Exception):
    """Bad input or a failed external step, which reaches the user as one line and a non-zero
    exit (never a traceback); ``str(e)`` names the file, the field and what was expected. Raised
    by the command line (``tdem``) and by the validation cases below it, which both import it
    from here (``tdem/errors.py`` gives it its command-line name)."""
