"""Physical limits shared by the scene reader (which refuses values beyond them) and the
solvers' physics checks (which flag results beyond them). SI units."""

# The highest temperature a scene may give and a run may reach without a flag (K): no solid
# remains one above it (the highest melting point known is ~4,300 K, tungsten boils at
# 5,930 K), so a model of solid spheres with constant properties means nothing there. Below
# 0 K nothing at all.
TEMPERATURE_MAX_K = 1.0e4
