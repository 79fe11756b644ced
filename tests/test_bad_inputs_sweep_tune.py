"""Bad inputs of sweep records, study files and a video path: each exits 2 with one line naming it, and leaves
the files it found as they were (a sweep's records are never overwritten unless they can be verified to be its own).
"""

import os
import subprocess
from pathlib import Path

import pytest

from nextage_qp.cli import main

ROOT = Path(__file__).resolve().parents[1]
PUSH = str(ROOT / "configs" / "push_cube.yaml")
SWEEP = str(ROOT / "configs" / "sweeps" / "push_cube.yaml")


def refused(argv: list[str], capsys: pytest.CaptureFixture[str], expected: str) -> str:
    """Run the CLI; assert exit 2 and one stderr line (no traceback) holding ``expected``; the line."""
    assert main(argv) == 2
    err = capsys.readouterr().err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and "Traceback" not in err, err
    assert "error" in lines[0] and expected in lines[0], lines[0]
    return lines[0]


def files(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir())}


def sweep(out: Path, *extra: str) -> list[str]:
    return ["sweep", SWEEP, "--workers", "1", "--n", "2", "--set", "timing.settle=0", "--out", str(out), *extra]


@pytest.mark.parametrize("resume", [False, True], ids=["new", "resume"])
@pytest.mark.parametrize("header", ["{bad", "[1,2]", '{"seed": 0}'], ids=["not json", "a list", "no fingerprint"])
def test_a_sweep_json_this_tool_did_not_write_is_refused_and_kept(tmp_path, capsys, header, resume):
    out = tmp_path / "out"
    out.mkdir()
    (out / "sweep.json").write_text(header)
    (out / "episodes.jsonl").write_text('{"index": 0}\n')
    before = files(out)
    line = refused(sweep(out, *(["--resume"] if resume else [])), capsys,
                   f"{out / 'sweep.json'} is not a sweep record this tool wrote")
    assert "choose another --out, or remove the file" in line
    assert files(out) == before


@pytest.mark.parametrize("resume", [False, True], ids=["new", "resume"])
def test_episodes_without_a_sweep_json_are_never_overwritten(tmp_path, capsys, resume):
    out = tmp_path / "out"
    out.mkdir()
    (out / "episodes.jsonl").write_text('{"index": 0, "status": "success"}\n')
    before = files(out)
    refused(sweep(out, *(["--resume"] if resume else [])), capsys,
            f"--out {out}: holds {out / 'episodes.jsonl'} but no sweep.json, so it cannot be verified")
    assert files(out) == before


def study(tmp_path: Path, space: str) -> str:
    path = tmp_path / "study.yaml"
    path.write_text(f"sweep: {{file: {SWEEP}, episodes: 2, seed: 1}}\ntrials: 1\nspace:\n  {space}\n")
    return str(path)


def test_a_study_key_of_an_unknown_kind_lists_the_names_a_file_writes(tmp_path, capsys):
    line = refused(["tune", study(tmp_path, "ik.position_cost: {uniform: [0.3, 3.0]}"), "--out", str(tmp_path / "o")],
                   capsys, "space.ik.position_cost: unknown key 'uniform'; valid: float, log, int, choice, also")
    assert "integer" not in line
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("space", ["seed: {int: [0, 10]}", "ik.posture_cost: {log: [0.001, 0.1], also: [seed]}"],
                         ids=["searched", "tied"])
def test_a_study_searching_the_episode_seed_is_refused(tmp_path, capsys, space):
    refused(["tune", study(tmp_path, space), "--out", str(tmp_path / "o")], capsys,
            "study.yaml: space.seed: the sweep sets each episode's run seed itself")
    assert not (tmp_path / "o").exists()


def test_a_video_over_a_file_that_cannot_be_written_is_refused_before_the_run(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("MUJOCO_GL", os.environ.get("MUJOCO_GL", "egl"))
    video = tmp_path / "v.mp4"
    video.write_bytes(b"old")
    video.chmod(0o444)
    immutable = os.access(video, os.W_OK)  # root writes a read-only file: make it immutable instead
    if immutable and subprocess.run(["chattr", "+i", str(video)], capture_output=True).returncode != 0:
        pytest.skip("cannot make a file unwritable here (root without chattr)")
    try:
        line = refused(["run", PUSH, "--set", "timing.settle=0", "--video", str(video)], capsys,
                       f"--video {video}: cannot write the file (")
        assert "read-only or no permission" in line
    finally:
        if immutable:
            subprocess.run(["chattr", "-i", str(video)], check=True)
    assert video.read_bytes() == b"old"
