"""Reach test of robot files drafted by ``robot init``: targets from the FK of random in-range poses near home.

For each robot file and each arm: N configurations (home + normal noise, sigma 0.3 rad, clipped to the ranges, the
arm's joints only; poses where the robot touches itself or the floor are redrawn), the arm's wrist frame's world
position there as the target, then ``nextage-qp reach --robot FILE --frame WRIST --pos X Y Z`` (in process).
Prints how many targets each arm reached within 1 mm.

    .venv/bin/python tools/robot_init_reach.py robots_tmp/yumi.yaml robots_tmp/aloha.yaml [--n 20] [--seed 0]
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json

import mujoco
import numpy as np

from nextage_qp.cli import main as cli
from nextage_qp.robots.model import Robot


def targets(robot: Robot, arm: str, n: int, rng: np.random.Generator, sigma: float = 0.3) -> list[np.ndarray]:
    """World positions of the arm's wrist at ``n`` collision-free random poses near home."""
    m = robot.model
    d = mujoco.MjData(m)
    idx = robot.group(f"{arm}_arm")
    home = robot.keyframe_q("home")
    kind, fid = robot.frame(robot.description.arm(arm).wrist)
    out: list[np.ndarray] = []
    for _ in range(50 * n):
        q = home.copy()
        q[idx] = np.clip(home[idx] + rng.normal(0, sigma, len(idx)), robot.lower[idx], robot.upper[idx])
        robot.set_q(d, q)
        mujoco.mj_forward(m, d)
        if d.ncon:
            continue
        out.append((d.site_xpos[fid] if kind == "site" else d.xpos[fid]).copy())
        if len(out) == n:
            break
    return out


def main() -> None:
    """Run the reach test on each robot file given."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("files", nargs="+")
    ap.add_argument("--n", type=int, default=20)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    for file in args.files:
        robot = Robot.from_scene("scene", robot=file)
        for k, arm in enumerate(robot.arms):
            rng = np.random.default_rng(args.seed + k)
            errors = []
            for pos in targets(robot, arm.name, args.n, rng):
                out, err = io.StringIO(), io.StringIO()
                with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
                    code = cli(["reach", "--robot", file, "--frame", arm.wrist, "--json", "--pos", *map(str, pos)])
                if code == 2:
                    raise SystemExit(f"{file}: {err.getvalue().strip()}")
                errors.append(json.loads(out.getvalue())["final_error_m"])
            e = np.array(errors)
            print(f"{file} {arm.name} ({arm.wrist}): {int(np.sum(e <= 1e-3))}/{len(e)} within 1 mm; "
                  f"median {np.median(e) * 1e3:.3f} mm, worst {e.max() * 1e3:.3f} mm", flush=True)


if __name__ == "__main__":
    main()
