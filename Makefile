# tdem: `make demo` runs the main job on the default scene, `make test` runs the test suite.
# Both first install what is missing: Debian's YADE and python3-h5py (apt), then tdem and its
# Python dependencies in a virtualenv (.venv). YADE never runs inside the venv (tdem/yade.py).
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
SUDO   := $(shell [ "$$(id -u)" = 0 ] || echo sudo)
APT_PACKAGES := yade python3-h5py python3-scipy python3-venv liggghts openmpi-bin

.PHONY: demo test test-fast coverage deps apt validate bench bench-packings bench-walled bench-bed bench-peers clean

demo: deps
	$(BIN)/tdem demo

test: deps
	$(BIN)/python -m pytest -q

# The day-to-day subset (~45 s): no YADE, no LIGGGHTS, none of the tests marked slow in
# tests/conftest.py. `make test` runs them all.
test-fast: deps
	$(BIN)/python -m pytest -q -m "not yade and not liggghts and not slow"

# Coverage of thermal_kernel, the jitted kernels included (they run as Python): docs/solvers.md.
KERNEL_TESTS := tests/test_laws.py tests/test_solvers.py tests/test_max_principle.py \
	tests/test_analytic.py tests/test_hard_cases.py tests/test_run_scenes.py tests/test_scene.py \
	tests/test_packing_format.py tests/test_calibrate.py tests/test_checkpoint.py \
	tests/test_threading_layer.py
coverage: deps
	NUMBA_DISABLE_JIT=1 $(BIN)/python -m pytest -q -m "not yade and not liggghts" \
	    --cov=thermal_kernel --cov-report=term $(KERNEL_TESTS)

deps: apt $(VENV)/.installed

# Installs only when something is missing, so a second `make` costs nothing.
apt:
	@if ! command -v yade >/dev/null 2>&1 || ! command -v liggghts >/dev/null 2>&1 || ! command -v mpirun >/dev/null 2>&1 \
	    || ! /usr/bin/python3 -c "import h5py, scipy" >/dev/null 2>&1 \
	    || ! $(PYTHON) -m venv --help >/dev/null 2>&1; then \
	  echo "installing Debian packages: $(APT_PACKAGES)"; \
	  $(SUDO) apt-get update && \
	  DEBIAN_FRONTEND=noninteractive $(SUDO) apt-get install -y $(APT_PACKAGES); \
	fi

$(VENV)/.installed: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test]'
	touch $@

# Benchmarks (not tests): they measure and write bench/results/*, which docs/solvers.md quotes.
bench: deps
	$(BIN)/python bench/bench_explicit.py > bench/results/explicit_layout.txt
	$(BIN)/python bench/bench_explicit.py --memory 8e6 >> bench/results/explicit_layout.txt
	$(BIN)/python bench/bench_solvers.py

# Packing paths side by side (hours: the reference relaxes 10,000 spheres for ~1 h per seed);
# resumable (--reuse keeps the cases already built). Writes bench/results/packings.{csv,md,png},
# quoted by docs/packings.md.
# Walled boxes at scale (issue 24): the direct 1e4 reference (3 seeds) against the shell path;
# builds what is missing (hours), writes bench/results/walled.md and docs/img/walled_profiles.png.
bench-walled: deps
	$(BIN)/python bench/bench_walled.py --build

bench-packings: deps
	$(BIN)/python bench/bench_packings.py --reuse

# The 7,500-sphere bed series, the generator of 0c04f14 against today's, one YADE process at a
# time (~10 min): bench/results/bed_series_7500_idle.{csv,md}, quoted by docs/packings.md.
bench-bed: deps
	$(BIN)/python bench/bench_bed.py --scene runs/bed_7500.toml --seeds 1 --stem bed_series_7500_idle --force

# Peers side by side (issue 27): YADE's ThermalEngine, LIGGGHTS' conduction fix and tdem on the
# same LIGGGHTS-made beds of 2e3, 1e4 and 5e4 spheres, one run, both cores (~30 min; the beds
# are kept in bench/out/peers and reused): bench/results/peers.{csv,md}, docs/peers.md's table.
bench-peers: deps
	$(BIN)/python bench/bench_peers.py

# Long validation: the 7,500-sphere pressure campaign of the pipe-model paper (YADE ~3 min,
# thermal ~3 min), quoted in docs/campaign.md; the ETC of composites on the 10,000-sphere dense
# box (YADE ~4 min), quoted in docs/post.md; then every case of docs/validation.md (the papers'
# own cases; resumable: a case with validation/results/caseN.json is skipped), which rewrites
# docs/validation.md and the summary in README.md.
validate: deps
	$(BIN)/tdem campaign runs/campaign_7500.toml
	test -f runs/out/dense_box_10k/packing.h5 || $(BIN)/tdem pack runs/dense_box_10k.toml
	$(BIN)/tdem etc runs/dense_box_10k.toml
	$(BIN)/tdem validate

clean:
	rm -rf $(VENV) runs/out .pytest_cache .coverage
