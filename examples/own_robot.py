"""Your own robot: draft a robot file from a model, check it, and reach a target with each hand.

    python examples/own_robot.py [--model tests/data/robots/two_arms.xml] [--out DIR]

``nextage-qp robot init MODEL`` does the drafting from the command line; here it is done in Python and the draft
(joints by arm, wrist frames, collision groups, torque limits) is used as it is.
"""

import argparse
import tempfile
from pathlib import Path

import numpy as np

import nextage_qp as nq
from nextage_qp.experiments.reach import run_reach
from nextage_qp.kinematics.frames import Kinematics
from nextage_qp.robots.check_report import check_robot
from nextage_qp.robots.draft import draft_text, write_draft
from nextage_qp.robots.gains import robot_gains
from nextage_qp.robots.survey import survey

ROOT = Path(__file__).resolve().parents[1]  # the repository: its configs and test models

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--model", default=str(ROOT / "tests" / "data" / "robots" / "two_arms.xml"),
                    help="an MJCF or URDF robot model")
parser.add_argument("--out", default=None, help="folder for the drafted robot file (default: a temporary one)")
args = parser.parse_args()

out = Path(args.out or tempfile.mkdtemp()) / "my_robot.yaml"
out.parent.mkdir(parents=True, exist_ok=True)
write_draft(draft_text(survey(Path(args.model)), out), out, force=True)
print(f"drafted {out}")
report = check_robot(out)  # `nextage-qp robot check FILE`: one line and a fix per problem
print(f"robot check: {len(report.problems)} problem(s)" + "".join(f"\n  {p}" for p in report.problems))

robot = nq.load_robot(out)
print(f"{robot.name}: {robot.nq} joints, arms {[arm.name for arm in robot.arms]}")
kin, home = Kinematics(robot), robot.keyframe_q("home")
for arm in robot.arms:
    goal = kin.fk(arm.wrist, home).pos + np.array([0.05, 0.0, 0.05])  # 7 cm away, forward and up
    result, _ = run_reach(robot, arm.wrist, goal, gains=robot_gains(robot), duration=3.0)
    print(f"  {arm.name} arm: {arm.wrist} reached within {result.final_error_m * 1e3:.2f} mm")
    assert result.final_error_m < 0.005
