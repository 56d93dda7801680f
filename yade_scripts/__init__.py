"""The YADE side of tdem: the packing generators and their pure parts.

The generators ``dense_packing.py`` and ``compressed_bed.py`` are scripts run by Debian's YADE
(``yade -n -x SCRIPT params.json``, launched by ``tdem pack``); they import YADE only inside
``main()`` and run it only as ``__main__``. Everything that does not need YADE lives in pure
modules (numpy, scipy and the standard library), importable as ``yade_scripts.<name>`` by plain
pytest and loaded by ``tdem pack`` (``tdem.yade.scripts_module``) to check parameters before
YADE starts:

- ``params``: the parameter schemas' machinery; ``dense_params`` / ``bed_params``: the schemas
  and their cross-field checks;
- ``placement``: random sequential addition, the one placement routine (also used by
  ``tdem_post/etc_sweep.py``, which loads it by path);
- ``dense_geometry`` / ``bed_geometry``: radii, domains, clouds, phases, contacts from arrays;
- ``neighbours``, ``tiling``: neighbour search, periodic-cell tiling;
- ``tdem_dump`` / ``tdem_yade``: the packing writer, and the dump of any user's YADE scene.

This folder imports neither ``thermal_kernel`` nor ``tdem_post`` as packages: it loads the
single packing writer (``thermal_kernel/packing_h5.py``) by path and speaks to the rest only
through the packing file.
"""
