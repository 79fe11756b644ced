"""``run --rerun``: a recording Rerun's own tools read back, with the scene, the joints and the phases in it."""

import importlib.util
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from nextage_qp.cli import main

ROOT = Path(__file__).resolve().parents[1]
needs_rerun = pytest.mark.skipif(importlib.util.find_spec("rerun") is None,
                                 reason="rerun-sdk is not installed (the rerun extra)")


def _rerun_cli(*args: str, home: Path) -> subprocess.CompletedProcess:
    exe = shutil.which("rerun") or str(Path(sys.executable).parent / "rerun")  # the venv's, beside its python
    env = {**os.environ, "HOME": str(home), "XDG_CONFIG_HOME": str(home), "CI": "1"}  # no analytics, a clean home
    return subprocess.run([exe, *args], capture_output=True, text=True, env=env, timeout=120)


@needs_rerun
@pytest.mark.slow
def test_push_recording_reads_back_with_the_scene_and_the_signals(tmp_path: Path) -> None:
    path = tmp_path / "push.rrd"
    assert main(["run", str(ROOT / "configs" / "push_cube.yaml"), "--rerun", str(path)]) == 0
    assert path.stat().st_size > 100_000
    verified = _rerun_cli("rrd", "verify", str(path), home=tmp_path)
    assert verified.returncode == 0, verified.stderr
    printed = _rerun_cli("rrd", "print", str(path), home=tmp_path)
    assert printed.returncode == 0, printed.stderr
    entities = {part.split()[0] for part in printed.stdout.split(" - /")[1:]}
    for name in ("world/LARM_JOINT5_Link", "world/cube", "world/cube_target", "world/table",  # robot, object...
                 "joints/LARM_JOINT1/q", "joints/LARM_JOINT1/q_ref", "joints/LARM_JOINT1/q_cmd",
                 "joints/LARM_JOINT1/tau", "tools/left_tool/measured", "tools/left_tool/commanded",
                 "objects/cube/truth", "contacts/cube", "phases"):
        assert name in entities, (name, sorted(entities)[:40])


@needs_rerun
def test_an_unwritable_recording_path_is_one_line(tmp_path: Path, capsys) -> None:
    assert main(["run", str(ROOT / "configs" / "push_cube.yaml"), "--rerun", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert len([ln for ln in err.splitlines() if ln.strip()]) == 1 and "--rerun" in err
