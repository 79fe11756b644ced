import os

import pytest

os.environ.setdefault("MUJOCO_GL", "egl")

from nextage_qp.robots.model import Robot


@pytest.fixture(scope="session")
def robot() -> Robot:
    return Robot.from_scene("scene")


@pytest.fixture(scope="session")
def push_robot() -> Robot:
    return Robot.from_scene("push_cube")


@pytest.fixture(scope="session")
def dock_robot() -> Robot:
    return Robot.from_scene("dock_dumbbell")
