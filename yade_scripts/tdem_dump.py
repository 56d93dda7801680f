"""Loads tdem's packing writer (``thermal_kernel/packing_h5.py``) by file path.

The generators run under YADE on Debian's Python, where the ``thermal_kernel`` package (numba,
scipy, ...) is not importable; ``packing_h5.py`` needs only numpy and h5py, so it is loaded on its
own. One writer therefore serves YADE and the project side, and both write identical files.
"""
import importlib.util
import os

_path = os.path.join(os.path.dirname(os.path.abspath(__file__)), os.pardir,
                     "thermal_kernel", "packing_h5.py")
_spec = importlib.util.spec_from_file_location("tdem_packing_h5", _path)
_module = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(_module)

write_packing = _module.write_packing
FORMAT = _module.FORMAT
FORMAT_VERSION = _module.FORMAT_VERSION
