"""Parameter schemas of the packing generators, shared by YADE and by ``tdem pack``.

Each generator has one schema module (``dense_params.py``, ``bed_params.py``) that defines
``PARAMS = {name: dict(kind=..., default=..., help=..., choices=..., minimum=...,
maximum=...)}`` (plain data)
and ``check(p)``, its cross-field checks on the resolved parameters (a combination of values,
e.g. a softened modulus above the real one, or a domain too small for its spheres). ``tdem pack``
resolves a scene's ``[pack]`` table against the schema and runs the checks (so a user gets a
one-line error naming the scene file and key before YADE starts), then hands the complete set to
the YADE script as JSON; the script resolves and checks it again with the same code, so it can
also be run by hand. Standard library only here; the checks may use the generators' pure
geometry modules (numpy, scipy), which both sides have.
"""
import importlib
import json
import math
import os


class ParamError(ValueError):
    """A bad generator parameter; the message names the key and what was expected."""


class Param:
    """One parameter: expected type ('float', 'int', 'str', 'bool', 'floats', 'list'),
    default (None = required), allowed choices, a one-line help text with its SI unit."""

    def __init__(self, kind, default, help, choices=None, minimum=None, maximum=None):
        self.kind = kind
        self.default = default
        self.help = help
        self.choices = choices
        self.minimum = minimum
        self.maximum = maximum

    def check(self, key, value):
        kind = self.kind
        if kind == "float":
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise ParamError(f"{key}: expected a number, got {value!r}")
            value = float(value)
            if not math.isfinite(value):
                raise ParamError(f"{key}: expected a finite number, got {value!r}")
        elif kind == "int":
            if isinstance(value, bool) or not isinstance(value, int):
                raise ParamError(f"{key}: expected an integer, got {value!r}")
        elif kind == "str":
            if not isinstance(value, str):
                raise ParamError(f"{key}: expected a string, got {value!r}")
        elif kind == "bool":
            if not isinstance(value, bool):
                raise ParamError(f"{key}: expected true or false, got {value!r}")
        elif kind == "floats":
            if not isinstance(value, (list, tuple)) or not all(
                    isinstance(v, (int, float)) and not isinstance(v, bool) for v in value):
                raise ParamError(f"{key}: expected a list of numbers, got {value!r}")
            value = [float(v) for v in value]
            if not all(math.isfinite(v) for v in value):
                raise ParamError(f"{key}: expected finite numbers, got {value!r}")
        elif kind == "list":
            if not isinstance(value, (list, tuple)):
                raise ParamError(f"{key}: expected a list, got {value!r}")
            value = list(value)
        if self.choices is not None and value not in self.choices:
            raise ParamError(f"{key}: expected one of {', '.join(map(str, self.choices))}, "
                             f"got {value!r}")
        for v in value if isinstance(value, list) else [value]:
            if not isinstance(v, (int, float)):
                continue
            if self.minimum is not None and v < self.minimum:
                raise ParamError(f"{key}: expected a value >= {self.minimum}, got {v!r}")
            if self.maximum is not None and v > self.maximum:
                raise ParamError(f"{key}: expected a value <= {self.maximum}, got {v!r}")
        return value


def resolve(schema, table):
    """Return a complete parameter dict: defaults filled in, every key checked.

    Raises ParamError naming the first unknown, missing or ill-typed key."""
    unknown = sorted(set(table) - set(schema))
    if unknown:
        raise ParamError(f"{unknown[0]}: unknown key (known: {', '.join(sorted(schema))})")
    out = {}
    for key, spec in schema.items():
        param = spec if isinstance(spec, Param) else Param(**spec)
        if key in table:
            out[key] = param.check(key, table[key])
        elif param.default is None:
            raise ParamError(f"{key}: missing required key ({param.help})")
        else:
            out[key] = param.default
    return out


def schema_module(generator):
    """The schema module of a generator ('dense' or 'bed'): ``<generator>_params`` of this
    package."""
    return importlib.import_module(f"{__package__}.{generator}_params")


def load_schema(generator):
    """The PARAMS dict of a generator ('dense' or 'bed')."""
    return schema_module(generator).PARAMS


def check(generator, p):
    """The generator's cross-field checks on resolved parameters ``p``; ParamError naming the
    key."""
    try:
        schema_module(generator).check(p)
    except ParamError:
        raise
    except ValueError as e:
        raise ParamError(str(e)) from None


def resolve_and_check(generator, table):
    """Defaults filled in, every key checked, then the cross-field checks: what ``tdem pack``
    and the YADE scripts run on a parameter table."""
    p = resolve(load_schema(generator), table)
    finish = getattr(schema_module(generator), "finish", None)
    if finish is not None:      # values that stand for others (dense: method = "auto")
        finish(p)
    check(generator, p)
    return p


def read_params_json(path, generator):
    """Used by the YADE scripts: read the JSON written by ``tdem pack`` (or by hand), resolved
    and checked."""
    with open(path) as f:
        table = json.load(f)
    return resolve_and_check(generator, table)


def params_path_from_argv_or_batch(argv, script):
    """The params.json of a generator run: ``yade -x SCRIPT params.json``, or, under
    ``yade-batch TABLE SCRIPT``, the ``params_json`` column of the job's table line (YADE sets
    YADE_BATCH=table:line for each job). None when neither is given."""
    if len(argv) == 2:
        return argv[1]
    if os.environ.get("YADE_BATCH"):
        from yade import utils
        utils.readParamsFromTable(params_json="", noTableOk=False)
        from yade.params import table
        return table.params_json or None
    return None
