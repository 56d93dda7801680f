"""The YADE side of tdem: the packing generators and their pure parts.

The generators ``dense_packing.py`` and ``compressed_bed.py`` are scripts run by Debian's YADE
(``yade -n -x SCRIPT params.json``, launched by ``tdem pack``); they import YADE only inside
``main()`` and run it only as ``__main__``. Everything that does not need YADE lives in pure
modules (numpy, scipy and the standard library), importable as ``yade_scripts.<name>`` by plain
pytest and loaded by ``tdem pack`` (``tdem.yade.scripts_module``) to check parameters before
YADE starts:

- ``params``: the parameter schemas' machinery; ``dense_params`` / ``bed_params``: the schemas
  and their cross-field checks;
- ``placement``: random sequential addition, the one placement routine, whose home is
  ``thermal_kernel/placement.py`` (numpy only; the ETC sweep of ``tdem_post`` uses it too);
- ``dense_geometry`` / ``bed_geometry``: radii, domains, clouds, phases, contacts from arrays;
- ``neighbours``, ``tiling``: neighbour search, periodic-cell tiling;
- ``tdem_dump`` / ``tdem_yade``: the packing writer, and the dump of any user's YADE scene.

Of ``thermal_kernel`` this folder imports only its numpy-only modules (``placement``;
``tests/test_layers.py`` holds the list and keeps them numpy-only), never ``tdem_post``; it loads
the single packing writer (``thermal_kernel/packing_h5.py``) by path and speaks to the rest only
through the packing file.
"""
