"""Conductance laws, registered by name (explicit dict, no discovery).

Each law is a :class:`~thermal_kernel.laws.base.Law`: a conductance function (W/K per contact),
a capacity function (J/K per particle), optionally a particle-wall conductance, a one-line
formula, a reference, its ``kind`` (which dumped rows conduct: geometric, force or overlap) and
default parameters. Laws with ``diagnostic = True`` are hypothesis
tools, not physical laws (``tdem laws`` lists them apart). ``docs/laws.md`` describes each one.
"""
from __future__ import annotations

from .base import Law
from .chaudhuri import CHAUDHURI
from .granular import ARGENTO, BOB, OTT, PIPE, PIPE_RESISTANCE_AS_CONDUCTANCE
from .haddad import HADDAD
from .liggghts import LIGGGHTS
from .terreros import TERREROS
from .yade import YADE

LAWS: dict[str, Law] = {
    "terreros": TERREROS,
    "haddad": HADDAD,
    "pipe": PIPE,
    "bob": BOB,
    "argento": ARGENTO,
    "ott": OTT,
    "chaudhuri": CHAUDHURI,
    "yade": YADE,
    "liggghts": LIGGGHTS,
    # diagnostic (law.diagnostic): a hypothesis tool, not a physical law (issue 15)
    "pipe_resistance_as_conductance": PIPE_RESISTANCE_AS_CONDUCTANCE,
}


class UnknownLawError(KeyError):
    """A law name that is not in :data:`LAWS`; the message lists the known names."""

    def __str__(self) -> str:          # KeyError would print the message with quotes
        return str(self.args[0]) if self.args else ""


def get_law(name: str) -> Law:
    """The registered law called ``name``; :class:`UnknownLawError` lists the names otherwise."""
    try:
        return LAWS[name]
    except (KeyError, TypeError):
        raise UnknownLawError(f"unknown law {name!r} (known: {', '.join(LAWS)})") from None


__all__ = ["LAWS", "Law", "UnknownLawError", "get_law"]
