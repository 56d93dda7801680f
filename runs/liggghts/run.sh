#!/bin/sh
# A LIGGGHTS series through tdem's whole report (docs/import.md). From the repository root:
#
#   sh runs/liggghts/run.sh            (TDEM=.venv/bin/tdem by default; NP=2 MPI ranks)
#
# 1. Debian's LIGGGHTS makes the bed on NP ranks (bed.in; skipped when the dumps exist),
# 2. `tdem import liggghts` turns each of the four stages into runs/out/liggghts/packing_<k>.h5,
# 3. `tdem campaign runs/liggghts/campaign.toml` runs, posts and reports on them.
set -e
here=$(cd "$(dirname "$0")" && pwd)
tdem=${TDEM:-$here/../../.venv/bin/tdem}
out=$(cd "$here/.." && pwd)/out/liggghts
mkdir -p "$out"
cd "$out"
if [ "$(id -u)" = 0 ]; then       # Open MPI refuses root unless told
    export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
fi
if [ ! -f walls_4.dump ]; then
    echo "liggghts: mpirun -np ${NP:-2} liggghts -in $here/bed.in (log: $out/liggghts.log)"
    mpirun -np "${NP:-2}" liggghts -in "$here/bed.in" -var src "$here" > liggghts.log
fi
for k in 1 2 3 4; do
    "$tdem" import liggghts atoms_$k.dump pairs_$k.dump walls_$k.dump \
        --walls zmin,plate:zmax --young 1e8 --poisson 0.2 --density 2500 -o packing_$k.h5
done
"$tdem" campaign "$here/campaign.toml" --out "$out/campaign"
