"""Every script in examples/ runs, as a user would run it, and says what it did."""

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = sorted((ROOT / "examples").glob("*.py"))
ARGS = {"sweep_from_python.py": ["--episodes", "2", "--workers", "2"]}
SAYS = {
    "run_and_plot.py": "success: True",
    "custom_phase.py": "done: the tool stayed within",
    "own_robot.py": "reached within",
    "sweep_from_python.py": "2/2 succeed",
    "collision_and_weights.py": "success: True",
}


def test_every_example_is_checked() -> None:
    assert {p.name for p in EXAMPLES} == set(SAYS) and len(EXAMPLES) >= 4


@pytest.mark.slow
@pytest.mark.parametrize("script", EXAMPLES, ids=[p.stem for p in EXAMPLES])
def test_example_runs(script: Path, tmp_path: Path) -> None:
    extra = ARGS.get(script.name, [])
    if script.name == "run_and_plot.py":
        extra = ["--out", str(tmp_path / "push.png")]
    if script.name == "own_robot.py":
        extra = ["--out", str(tmp_path)]
    done = subprocess.run([sys.executable, str(script), *extra], cwd=tmp_path, capture_output=True, text=True,
                          timeout=600)
    assert done.returncode == 0, done.stderr[-2000:]
    assert SAYS[script.name] in done.stdout, done.stdout
    if script.name == "run_and_plot.py":
        assert (tmp_path / "push.png").stat().st_size > 1000
