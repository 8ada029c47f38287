"""``scripts/stress.py`` runs its later probe classes by name and judges them: the quick
ones (huge axes, output-point limits, unclear errors, tampered maps) run here end to end,
in the script's own worker, and every call must end soundly or with a clear error."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: The classes run here: each call in them takes well under a second once warm.
QUICK = ("huge", "points", "tampered", "unclear")


def test_the_quick_later_classes_run_and_end_soundly_or_clearly(tmp_path: Path) -> None:
    out = tmp_path / "outcomes.json"
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    run = subprocess.run([sys.executable, str(ROOT / "scripts" / "stress.py"), "--classes",
                          ",".join(QUICK), "--cases", "0", "--files", "0", "--json", str(out)],
                         capture_output=True, text=True, env=env, cwd=tmp_path, timeout=900)
    assert run.returncode == 0, run.stderr[-3000:]
    outcomes = json.loads(out.read_text())
    assert {o["class"] for o in outcomes} == set(QUICK)
    bad = [o for o in outcomes if o["kind"] != "clear" and (o["kind"] != "returned" or o["wrong"])]
    assert not bad, json.dumps(bad, indent=1)[:3000]
    table = run.stdout.splitlines()[-len(QUICK):]  # the per-class rows of the matrix
    assert [row.split()[0] for row in table] == list(QUICK)
