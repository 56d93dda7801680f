"""[campaign] packings = [files]: the list is checked before any case runs (one line naming the
campaign file and the entry, exit 2). The committed beds stand in for imported packings; the
runs themselves are covered by tests/test_liggghts.py's packings and docs/import.md."""
import shutil
import subprocess
import sys
from pathlib import Path

import h5py
import pytest

DATA = Path(__file__).resolve().parent / "data"
BED = DATA / "bed_small_1.6e+06Pa.h5"
TDEM = [sys.executable, "-m", "tdem.cli"]
SCENE = '''
[material]
conductivity = 205.0
density = 2500.0
heat_capacity = 900.0
young_pa = 5e10
poisson = 0.2
[initial]
temperature = 300.0
[solver]
method = "steady"
'''


def campaign(tmp, packings, extra=""):
    path = tmp / "camp.toml"
    path.write_text(f'[campaign]\nlaws = ["pipe"]\npackings = {packings}\n{extra}{SCENE}')
    r = subprocess.run([*TDEM, "campaign", str(path), "--out", str(tmp / "out")],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr
    assert len(r.stderr.strip().splitlines()) == 1
    assert not (tmp / "out").exists()
    return r.stderr


def test_missing_file(tmp_path):
    assert "campaign.packings[0]: " in campaign(tmp_path, '["nope.h5"]')


def test_nan_pressure_refused(tmp_path):
    shutil.copy(BED, tmp_path / "p.h5")
    with h5py.File(tmp_path / "p.h5", "r+") as f:
        f.attrs["pressure_pa"] = float("nan")
    err = campaign(tmp_path, '["p.h5"]')
    assert "campaign.packings[0]" in err and "pressure_pa is nan" in err


def test_invalid_packing_refused(tmp_path):
    shutil.copy(BED, tmp_path / "p.h5")
    with h5py.File(tmp_path / "p.h5", "r+") as f:
        f["particles/radius"][0] = -1.0
    err = campaign(tmp_path, '["p.h5"]')
    assert "campaign.packings[0]" in err and "particles/radius" in err


# slow: two refused `tdem campaign` subprocesses;
# over ~1.3 s on the shared 2-core machine, warm numba cache (--durations, 2026-12-01)
@pytest.mark.slow
def test_not_with_pack_or_seeds(tmp_path):
    shutil.copy(BED, tmp_path / "p.h5")
    assert "not both" in campaign(tmp_path, '["p.h5"]', '[pack]\ngenerator = "bed"\n')
    assert "drop campaign.seeds" in campaign(tmp_path, '["p.h5"]\nseeds = [1, 2]')


def test_same_names_refused(tmp_path):
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    shutil.copy(BED, tmp_path / "a" / "p.h5")
    shutil.copy(BED, tmp_path / "b" / "p.h5")
    assert "same name as packings[0]" in campaign(tmp_path, '["a/p.h5", "b/p.h5"]')
