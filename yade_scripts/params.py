"""Parameter schemas of the packing generators, shared by YADE and by ``tdem pack``.

Each generator has one schema module (``dense_params.py``, ``bed_params.py``) that imports
nothing and defines ``PARAMS = {name: dict(kind=..., default=..., help=..., choices=...,
minimum=...)}``. ``tdem pack`` checks a scene's ``[pack]`` table against it (so a
user gets a one-line error naming the scene file and key before YADE starts), resolves the
defaults and hands the complete set to the YADE script as JSON; the script resolves it again with
the same schema, so it can also be run by hand. Standard library only: this file is loaded by
path on Debian's Python inside YADE.
"""
import importlib.util
import json
import math
import os

_HERE = os.path.dirname(os.path.abspath(__file__))


class ParamError(ValueError):
    """A bad generator parameter; the message names the key and what was expected."""


class Param:
    """One parameter: expected type ('float', 'int', 'str', 'bool', 'floats', 'list'),
    default (None = required), allowed choices, a one-line help text with its SI unit."""

    def __init__(self, kind, default, help, choices=None, minimum=None):
        self.kind = kind
        self.default = default
        self.help = help
        self.choices = choices
        self.minimum = minimum

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
        if self.minimum is not None:
            values = value if isinstance(value, list) else [value]
            for v in values:
                if isinstance(v, (int, float)) and v < self.minimum:
                    raise ParamError(f"{key}: expected a value >= {self.minimum}, got {v!r}")
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


def load_schema(generator):
    """The PARAMS dict of a generator ('dense' or 'bed'), loaded by file path."""
    path = os.path.join(_HERE, f"{generator}_params.py")
    spec = importlib.util.spec_from_file_location(f"tdem_{generator}_params", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.PARAMS


def read_params_json(path, generator):
    """Used by the YADE scripts: read the JSON written by ``tdem pack`` (or by hand)."""
    with open(path) as f:
        table = json.load(f)
    return resolve(load_schema(generator), table)


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
