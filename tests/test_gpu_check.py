"""benchmarks/gpu_check.py runs end to end on the strict CuPy stand-in: the first GPU finds no import or API error."""

import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_strict_gpu_check_runs_end_to_end_on_the_stand_in(tmp_path):
    out = tmp_path / "report.json"
    # the tests part would start pytest inside pytest; the strict tests run in this suite anyway
    r = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "gpu_check.py"), "--stand-in", "--skip", "tests",
                        "--sizes", "16", "--repeats", "1", "-o", str(out)], capture_output=True, text=True, cwd=ROOT,
                       env={"PYTHONPATH": str(ROOT), "PATH": "/usr/bin:/bin", "HOME": str(tmp_path)})
    assert r.returncode == 0, r.stderr[-3000:]
    rep = json.loads(out.read_text())
    assert rep["device"].startswith("strict CuPy stand-in") and "stand-in" in rep["timer"]  # never GPU numbers
    t = rep["timings"]["16"]
    assert t["stokes_solve"]["median_ms"] > 0 and t["inextensible_step"]["median_ms"] > 0
    assert t["noise_field"]["median_ms"] > 0  # a noisy step's host draw, copy and transform
    assert rep["case"]["passed"] and rep["case"]["relative_difference"] <= 1e-3
    assert "pool_total_bytes" in rep["memory"]
    assert rep["stand_in_transfers"]["d2h"] > 0 and rep["stand_in_transfers"]["h2d"] > 0
