# tdem: `make demo` runs the main job on the default scene, `make test` runs the test suite.
# Both first install what is missing: Debian's YADE and python3-h5py (apt), then tdem and its
# Python dependencies in a virtualenv (.venv). YADE never runs inside the venv (tdem/yade.py).
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
SUDO   := $(shell [ "$$(id -u)" = 0 ] || echo sudo)
APT_PACKAGES := yade python3-h5py python3-scipy python3-venv liggghts openmpi-bin
# The PETSc backend (issue 25, docs/scaling.md): Debian's petsc4py, mpi4py and MPI-enabled h5py,
# built for Debian's python3 and numpy 1.24, so they run in a second venv, .venv-mpi (below).
# Without recommends: 37 packages, ~100 MB (with them apt pulls PETSc's compilers and headers).
MPI_APT_PACKAGES := python3-petsc4py python3-mpi4py python3-h5py-mpi
MPI_VENV := .venv-mpi

.PHONY: demo test test-fast coverage deps apt validate bench bench-packings bench-walled bench-bed bench-peers bench-scaling bench-ranks clean

demo: deps
	$(BIN)/tdem demo

test: deps
	$(BIN)/python -m pytest -q

# The day-to-day subset (~45 s): no YADE, no LIGGGHTS, none of the tests marked slow
# (@pytest.mark.slow at the test). `make test` runs them all.
test-fast: deps
	$(BIN)/python -m pytest -q -m "not yade and not liggghts and not slow"

# Coverage of thermal_kernel, the jitted kernels included (they run as Python): docs/solvers.md.
# The modules it counts say so themselves (pytestmark = pytest.mark.kernel); KERNEL_TESTS asks
# pytest which files they are, so that the coverage run imports only those (collecting every
# test module would count the import lines of modules no kernel test runs).
KERNEL_TESTS = $(shell $(BIN)/python -m pytest --collect-only -q -m kernel | grep '^tests/[^ ]*::' \
	| cut -d: -f1 | sort -u)
coverage: deps
	NUMBA_DISABLE_JIT=1 $(BIN)/python -m pytest -q -m "kernel and not yade and not liggghts" \
	    --cov=thermal_kernel --cov-report=term $(KERNEL_TESTS)

deps: apt $(VENV)/.installed $(MPI_VENV)/.installed

# Installs only when something is missing, so a second `make` costs nothing.
apt:
	@if ! command -v yade >/dev/null 2>&1 || ! command -v liggghts >/dev/null 2>&1 || ! command -v mpirun >/dev/null 2>&1 \
	    || ! /usr/bin/python3 -c "import h5py, scipy" >/dev/null 2>&1 \
	    || ! $(PYTHON) -m venv --help >/dev/null 2>&1; then \
	  echo "installing Debian packages: $(APT_PACKAGES)"; \
	  $(SUDO) apt-get update && \
	  DEBIAN_FRONTEND=noninteractive $(SUDO) apt-get install -y $(APT_PACKAGES); \
	fi
	@if ! dpkg -s $(MPI_APT_PACKAGES) >/dev/null 2>&1; then \
	  echo "installing Debian packages: $(MPI_APT_PACKAGES) (without recommends)"; \
	  $(SUDO) apt-get update && \
	  DEBIAN_FRONTEND=noninteractive $(SUDO) apt-get install -y --no-install-recommends $(MPI_APT_PACKAGES); \
	fi

$(VENV)/.installed: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test]'
	touch $@

# The PETSc backend's venv: Debian's python3 with its site-packages (numpy 1.24, scipy, mpi4py,
# h5py with MPI), petsc4py through a .pth (Debian reaches it through /usr/lib/petsc, an
# alternative that only petsc-dev sets), numba & co. from pip held to Debian's numpy and h5py,
# and tdem itself without its dependencies (its numpy>=2.0 is for tdem_post, which runs in .venv).
$(MPI_VENV)/.installed: pyproject.toml
	/usr/bin/python3 -m venv --system-site-packages $(MPI_VENV)
	echo '*' > $(MPI_VENV)/.gitignore
	ls -d /usr/lib/petscdir/petsc*/*-real/lib/python3/dist-packages | head -n 1 \
	  > $$($(MPI_VENV)/bin/python -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')/zz_petsc_debian.pth
	/usr/bin/python3 -c 'import numpy, h5py; print(f"numpy=={numpy.__version__}\nh5py=={h5py.__version__}")' \
	  > $(MPI_VENV)/constraints.txt
	$(MPI_VENV)/bin/python -m pip install --quiet -c $(MPI_VENV)/constraints.txt \
	  'numba>=0.58' 'threadpoolctl>=3.1' 'tqdm>=4.60' 'pyamg>=5.0'
	$(MPI_VENV)/bin/python -m pip install --quiet --no-deps -e .
	$(MPI_VENV)/bin/python -c 'from petsc4py import PETSc; import mpi4py, thermal_kernel.solvers.petsc_backend'
	touch $@

# Benchmarks (not tests): they measure and write bench/results/*, which docs/solvers.md quotes.
bench: deps
	$(BIN)/python bench/bench_explicit.py > bench/results/explicit_layout.txt
	$(BIN)/python bench/bench_explicit.py --memory 8e6 >> bench/results/explicit_layout.txt
	$(BIN)/python bench/bench_solvers.py

# The PETSc backend side by side with the in-process solvers (issue 25): N x ranks x solver,
# wall, memory, iterations, the cost model; writes docs/scaling.md (~10 min on 2 cores).
bench-scaling: deps
	$(BIN)/python bench/bench_scaling.py --write docs/scaling.md

# Issue 25's "same answers" on every scene of runs/: in-process against --ranks 1, 2, 3 (tdem
# run, tdem campaign), each thermal.h5 compared; packings from runs/out or made small (YADE, one
# at a time) under bench/out/ranks; writes bench/results/ranks_same_answers.md (docs/scaling.md).
bench-ranks: deps
	$(BIN)/python bench/ranks_same_answers.py

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
	rm -rf $(VENV) $(MPI_VENV) runs/out .pytest_cache .coverage
