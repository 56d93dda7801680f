"""The two committed 300-sphere beds (tests/data, made by YADE: tests/data/README.md) and the
scene text that heats them, shared by the tests, tools/same_outputs.py and bench/bench_solvers.py
so that none of these imports a module of tests/ (issue 26). Plain paths and strings, the
standard library only; the beds exist in a checkout (a wheel carries no tests/data).

- ``BED_THERMAL``: the thermal part of the pipe-model paper's bed scene (003, Table 1 and sec.
  4.4): glass-like spheres (k 205 W/m/K, rho 2500, c_p 900, E 5e10 Pa, nu 0.2) at 300 K between
  the bottom wall at 500 K and the plate at 400 K (runs/campaign_7500.toml has the same);
- ``BEDS``: the beds at 16 and 405 bar, which stand in for a campaign's built packings;
- ``NO_PACK``: a campaign of law pipe on them (no ``[pack]`` table: the caller gives ``BEDS`` as
  the packings), implicit, outputs at 5-200 s.
"""
from __future__ import annotations

from pathlib import Path

DATA = Path(__file__).resolve().parent.parent / "tests" / "data"
BEDS = [DATA / "bed_small_1.6e+06Pa.h5", DATA / "bed_small_4.05e+07Pa.h5"]

BED_THERMAL = '''
[material]
conductivity = 205.0
density = 2500.0
heat_capacity = 900.0
young_pa = 5e10
poisson = 0.2

[initial]
temperature = 300.0

[[boundary]]
kind = "temperature"
on = "zmin"
value = 500.0

[[boundary]]
kind = "temperature"
on = "plate"
value = 400.0
'''

NO_PACK = '[campaign]\nlaws = ["pipe"]\nn_bins = 5\n\n' + BED_THERMAL + """
[solver]
method = "implicit"
dt = 5.0
end_time = 200.0
output_times = [5.0, 10.0, 20.0, 50.0, 100.0, 200.0]
"""
