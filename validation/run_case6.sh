#!/bin/sh
# Case 6 of docs/validation.md over every packing at scale (resumable: done packings are skipped).
# The 8e6 box needs ~7.5 GB; it runs last.
set -e
cd "$(dirname "$0")/.."
export NUMBA_NUM_THREADS=${NUMBA_NUM_THREADS:-1} OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1
P=bench/out/packings
.venv/bin/python validation/case6_calibrate.py \
  walled_2000_s1=$P/ds_2000_s1/packing.h5 walled_2000_s2=$P/ds_2000_s2/packing.h5 \
  walled_2000_s3=$P/ds_2000_s3/packing.h5 walled_10000_s1=$P/ds_10000_s1/packing.h5 \
  walled_reference_10000_s1=$P/reference_10000_s1/packing.h5 \
  tiled_10000_s1=$P/tiled_10000_s1_c2000/packing.h5 tiled_10000_s2=$P/tiled_10000_s2_c2000/packing.h5 \
  tiled_10000_s3=$P/tiled_10000_s3_c2000/packing.h5 tiled_1e5_box=runs/out/dense_box_1e5/packing.h5 \
  tiled_1e5_cylinder=$P/tiled_100000_s1_c10000_cylinder/packing.h5 \
  tiled_1e6_box=$P/tiled_1000000_s1_c10000/packing.h5 \
  ${WITH_8E6:+tiled_8e6_box=$P/tiled_8000000_s1_c10000/packing.h5}
