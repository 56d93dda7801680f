"""The thermal part of the pipe-model paper's bed scene (003, Table 1 and sec. 4.4), shared by
the tests that run thermal scenes on YADE-made beds: glass-like spheres (k 205 W/m/K, rho 2500,
c_p 900, E 5e10 Pa, nu 0.2) at 300 K between the bottom wall at 500 K and the plate at 400 K."""

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
