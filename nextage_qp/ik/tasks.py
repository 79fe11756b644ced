"""The mink tasks of an IK step, built once per frame (or frame pair) and re-targeted every tick."""

from __future__ import annotations

from collections.abc import Callable, Sequence

import mink
import mujoco
import numpy as np

from nextage_qp.errors import ConfigError
from nextage_qp.ik.kinematic_model import Frame
from nextage_qp.ik.targets import FrameTarget, RelativeTarget


class TaskCache:
    """Frame, axis-align and relative-frame tasks, reused across ticks.

    Args:
        lm_damping: Levenberg-Marquardt damping of frame and axis tasks.
        position_cost: Default position weight [1/m].
        orientation_cost: Default orientation weight [1/rad].
        frame: Resolves a frame name.
    """

    def __init__(self, lm_damping: float, position_cost: float, orientation_cost: float,
                 frame: Callable[[str], Frame]) -> None:
        self.lm_damping, self.position_cost, self.orientation_cost = lm_damping, position_cost, orientation_cost
        self.frame = frame
        self._frame_tasks: dict[str, mink.FrameTask] = {}
        self._axis_tasks: dict[str, mink.AxisAlignTask] = {}
        self._axis_inputs: dict[str, tuple[list[float], list[float], float]] = {}  # axis, direction, cost last set
        self._relative_tasks: dict[tuple[str, str], mink.RelativeFrameTask] = {}

    def frames(self, targets: Sequence[FrameTarget], data: mujoco.MjData) -> list[mink.Task]:
        """Mink tasks for the targets, reusing one FrameTask / AxisAlignTask per frame across ticks."""
        tasks: list[mink.Task] = []
        for target in targets:
            frame = self.frame(target.frame)
            task = self._frame_tasks.get(frame.name)
            if task is None:
                task = mink.FrameTask(frame.name, frame.kind, 1.0, 1.0, lm_damping=self.lm_damping)
                # The task owns this target; every tick rewrites its array in place.
                task.transform_target_to_world = mink.SE3(wxyz_xyz=np.array([1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]))
                self._frame_tasks[frame.name] = task
            pcost = self.position_cost if target.position_cost is None else target.position_cost
            ocost = self.orientation_cost if target.orientation_cost is None else target.orientation_cost
            cost = task.cost
            cost[:3] = pcost if target.pos is not None else 0.0
            cost[3:] = ocost if target.rot is not None else 0.0
            # Without a rotation target, aim at the current rotation so the error twist is a pure translation.
            owned = task.transform_target_to_world
            assert owned is not None  # set when the task was made
            goal = owned.wxyz_xyz
            if target.rot is not None:
                mujoco.mju_mat2Quat(goal[:4], target.rot.reshape(9))
            else:
                mujoco.mju_mat2Quat(goal[:4], frame.xmat(data))
            goal[4:] = target.pos if target.pos is not None else frame.xpos(data)
            tasks.append(task)
            if target.axis is not None:
                axis_task = self._axis_tasks.get(frame.name)
                if axis_task is None:
                    axis_task = mink.AxisAlignTask(frame.name, frame.kind, lm_damping=self.lm_damping)
                    self._axis_tasks[frame.name] = axis_task
                # mink's setters validate and normalise: only when the inputs changed (a planner's descent asks the
                # same target every step)
                last, direction = self._axis_inputs.get(frame.name), np.asarray(target.direction)
                axis, aim = np.asarray(target.axis).tolist(), direction.tolist()  # lists: cheaper to compare
                if last is None or last[2] != ocost or last[0] != axis or last[1] != aim:
                    axis_task.set_axis(target.axis)
                    axis_task.set_cost(ocost)
                    axis_task.set_target(direction)
                    self._axis_inputs[frame.name] = (axis, aim, ocost)
                tasks.append(axis_task)
        return tasks

    def relative(self, targets: Sequence[RelativeTarget]) -> list[mink.Task]:
        """Mink relative-frame tasks for the targets, one per (frame, root) pair, reused across ticks."""
        tasks: list[mink.Task] = []
        for target in targets:
            key = (target.frame, target.root)
            task = self._relative_tasks.get(key)
            if task is None:
                frame, root = self.frame(target.frame), self.frame(target.root)
                task = mink.RelativeFrameTask(frame.name, frame.kind, root.name, root.kind,
                                              position_cost=target.cost, orientation_cost=target.cost)
                # The task owns this target; every tick rewrites its array in place.
                task.transform_target_to_root = mink.SE3(wxyz_xyz=np.array([1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]))
                self._relative_tasks[key] = task
            if not target.cost >= 0.0:
                raise ConfigError(f"relative target {target.frame!r} in {target.root!r}: cost must be >= 0, "
                                  f"got {target.cost}")
            task.cost[:] = target.cost
            owned = task.transform_target_to_root
            assert owned is not None  # set when the task was made
            goal = owned.wxyz_xyz
            mujoco.mju_mat2Quat(goal[:4], np.ascontiguousarray(target.rot, dtype=float).reshape(9))
            goal[4:] = target.pos
            tasks.append(task)
        return tasks
