"""install_component (distctrl/linuxcnc/hal_env.py): LinuxCNC's module directory is one per machine, shared
by every checkout that builds distctrl's components; an installed module built from another source (an
older or newer checkout, whatever its file times) is rebuilt, the same source is not."""
from __future__ import annotations

import os

from distctrl.linuxcnc import hal_env

COMP = '''component probe_dc "a probe";
pin out float out;
function _;
license "GPL";
;;
FUNCTION(_) { out = %s; }
'''


def test_a_module_built_from_another_source_is_rebuilt_whatever_the_file_times(tmp_path, monkeypatch):
    src_dir, mod_dir = tmp_path / "src", tmp_path / "mod"
    src_dir.mkdir()
    mod_dir.mkdir()
    monkeypatch.setattr(hal_env, "HAL_DIR", src_dir)
    monkeypatch.setattr(hal_env, "MODULE_DIR", mod_dir)
    src = src_dir / "probe_dc.comp"
    src.write_text(COMP % "1.0")
    target = hal_env.install_component("probe_dc")
    first = target.read_bytes()
    built = target.stat().st_mtime_ns
    assert hal_env.install_component("probe_dc").stat().st_mtime_ns == built      # the same source: kept
    # another checkout's source, older than the installed module (as a checkout made before it was built)
    src.write_text(COMP % "2.0")
    os.utime(src, (1_000_000_000, 1_000_000_000))
    assert hal_env.install_component("probe_dc").read_bytes() != first
