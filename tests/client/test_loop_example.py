"""R12 of the new-user audit and issue 39's "Done when": the copy-paste example of docs/commissioning.md
(examples/commissioning/loop.sh, which the page includes verbatim) runs as it is against
``distctrl serve`` on a free AMS/TCP port: excite, serve, record, identify, tune, write, check,
restore. Checked here, from the files the script leaves, with this test's own arithmetic:

* the excitation's recording is complete (its sidecar);
* after the write the served machine tracks no worse than before (RMS of
  ``DIST_CTRL::target_deviation`` over the passes that start inside each 8 s recording, each after its
  first 0.3 s), or tune's --json said that the set written tracks worse (``worse_than_current`` with a
  ``worse_reason`` for tuned.lis; for tuned-objects.lis its ``objects_set`` RMS above the current
  one's; keys read with .get: a tune without them still runs this test);
* the restore brings the old values back, and ``machine show`` says they are in effect.
"""
from __future__ import annotations

import json
import os
import re
import shutil
import socket
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from .conftest import pyads  # noqa: F401 - skips without the [ads] extra

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "examples" / "commissioning"

pytestmark = pytest.mark.loop


def test_the_page_shows_the_script_verbatim():
    page = (ROOT / "docs" / "commissioning.md").read_text(encoding="utf-8")
    script = (EXAMPLE / "loop.sh").read_text(encoding="utf-8")
    assert "```sh\n" + script + "```" in page


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def tracking_rms(path: Path) -> tuple[float, int]:
    """RMS of the deviation while ACTIVE over the activations that start in the recording, without the
    first 300 cycles of each; and how many there were."""
    data = np.genfromtxt(path, delimiter=",", names=True)
    dev, state = data["Zdeviation"], data["Zstate"]
    on = state == 2
    starts = [i for i in range(1, len(on)) if on[i] and not on[i - 1]]
    parts = []
    for a in starts:
        b = a
        while b < len(on) and on[b]:
            b += 1
        if b < len(on):                           # the pass ended inside the recording
            parts.append(dev[a + 300:b])
    x = np.concatenate(parts) if parts else np.zeros(0)
    return (float(np.sqrt(np.mean(x ** 2))) if len(x) else float("nan")), len(parts)


def last_show_block(text: str) -> str:
    blocks = text.split("axis Z (index 3)")
    return blocks[-1] if len(blocks) > 1 else ""


def test_the_documented_loop_runs_against_serve(tmp_path):
    work = tmp_path / "cl"
    shutil.copytree(EXAMPLE, work)
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    (bin_dir / "distctrl").write_text(f'#!/bin/sh\nexec "{sys.executable}" -m distctrl "$@"\n')
    (bin_dir / "distctrl").chmod(0o755)
    port = free_port()
    env = dict(os.environ, PATH=f"{bin_dir}:{os.environ['PATH']}", PYTHONPATH=str(ROOT), PORT=str(port),
               DISTCTRL_MACHINE_JOURNAL=str(tmp_path / "journal.json"), OPENBLAS_NUM_THREADS="1",
               OMP_NUM_THREADS="1", MKL_NUM_THREADS="1")
    r = subprocess.run(["sh", "loop.sh"], cwd=work, env=env, capture_output=True, text=True, timeout=1800)
    if r.returncode != 0 and "changes the filter, which the CNC objects cannot write" in r.stderr \
            and not (work / "tuned" / "tuned-objects.lis").exists():
        pytest.skip("tune chose another filter and wrote no tuned/tuned-objects.lis (an older tune): "
                    "machine write refused the list, as it must (issue 39, M3)")
    assert r.returncode == 0, (r.stdout[-3000:], r.stderr[-3000:])

    # the excitation's recording: complete
    side = json.loads((work / "excite_rec.csv.meta.json").read_text())
    assert side["complete"] is True and side["meta"]["cut_s"] == 0, side

    # tracking: no worse after the write, or tune said its set is worse and why
    before, n_before = tracking_rms(work / "before.csv")
    after, n_after = tracking_rms(work / "after.csv")
    assert n_before >= 1 and n_after >= 1, (n_before, n_after)
    tuned = json.loads((work / "tuned.json").read_text())
    current = ((tuned.get("scenario_params") or {}).get("metrics") or {}).get("rms_error")
    objects = ((tuned.get("objects_set") or {}).get("metrics") or {}).get("rms_error")
    wrote_objects = (work / "tuned" / "tuned-objects.lis").exists()
    if tuned.get("worse_than_current") and not wrote_objects:
        assert tuned.get("worse_reason"), tuned.get("worse_reason")
    elif wrote_objects and objects is not None and current is not None and objects > current:
        pass        # tune's JSON said the set kept with the machine's filter tracks worse on the twin
    else:
        # 5 %: the probe's noise and where the passes fall differ between the two recordings
        assert after <= 1.05 * before, (before, after, r.stdout[-3000:])
    print(f"tracking RMS before {before:.4f} mm ({n_before} passes), after {after:.4f} mm ({n_after}); "
          f"tune worse_than_current={tuned.get('worse_than_current')}", file=sys.stderr)

    # the restore: machine_z.lis's values in effect again, nothing pending
    old_kp = 0.08
    block = last_show_block(r.stdout)
    kp = re.search(r"kenngr\.distc\.kp\s+(\S+)", block)
    assert kp and float(kp.group(1)) == pytest.approx(old_kp) and "pending" not in block, block
