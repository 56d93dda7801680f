"""The YADE side's name for the one placement routine, ``thermal_kernel/placement.py`` (random
sequential addition; numpy only, so YADE's Python imports it with the repository on its path, as
the generators put it there). Its home is below both the generators and ``tdem_post``'s ETC sweep.
"""
from thermal_kernel.placement import equal_spheres_for_volume, random_sequential_addition

__all__ = ["equal_spheres_for_volume", "random_sequential_addition"]
