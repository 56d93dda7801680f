"""An interrupted `tdem pack` stops YADE with it (issue 28: after SIGTERM, YADE went on running
on its own). YADE for real: the 2,000-sphere box of runs/dense_box.toml, terminated while it
compresses."""
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tdem.yade import yade_environment

pytestmark = [pytest.mark.yade,
              pytest.mark.skipif(shutil.which("yade", path=yade_environment()["PATH"]) is None,
                                 reason="Debian's yade is not installed")]

ROOT = Path(__file__).resolve().parent.parent


def _default_sigint():
    # a test run started in the background (nohup, `make test &`) inherits SIGINT ignored, and
    # Python then installs no KeyboardInterrupt handler: give the child the default disposition
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _running(pattern: str) -> bool:
    return subprocess.run(["pgrep", "-f", pattern], capture_output=True).returncode == 0


@pytest.mark.parametrize("sig, status", [(signal.SIGTERM, 143), (signal.SIGINT, 130)])
def test_interrupted_pack_stops_yade(tmp_path, sig, status):
    out = tmp_path / "o"
    proc = subprocess.Popen([sys.executable, "-m", "tdem.cli", "pack",
                             str(ROOT / "runs" / "dense_box.toml"), "--out", str(out)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=_default_sigint)
    params = str(out / "params.json")
    for _ in range(600):                 # until YADE runs the script (it writes yade.log)
        if _running(params) and (out / "yade.log").exists():
            break
        time.sleep(0.1)
    assert _running(params)
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == status, err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
    for _ in range(100):
        if not _running(params):
            break
        time.sleep(0.1)
    assert not _running(params), "YADE still running after tdem was interrupted"
    assert not list(out.glob("packing*.h5"))
