import pydantic
import pytest

from nextage_qp.ik import CollisionPairConfig, IKConfig


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"position_cost": -1.0}, "greater than or equal"),
        ({"orientation_cost": -0.1}, "greater than or equal"),
        ({"posture_cost": -1.0}, "greater than or equal"),
        ({"damping": -1.0}, "greater than or equal"),
        ({"lm_damping": -1.0}, "greater than or equal"),
        ({"pos_tol": 0.0}, "greater than"),
        ({"rot_tol": -1.0}, "greater than"),
        ({"dt": 0.0}, "greater than"),
        ({"max_iters": 0}, "greater than or equal"),
        ({"restarts": -1}, "greater than or equal"),
        ({"stall_iters": 0}, "greater than or equal"),
        ({"limit_gain": 1.5}, "less than or equal"),
        ({"collision_gain": 0.0}, "greater than"),
        ({"velocity_limit": -1.0}, "velocity_limit"),
        ({"velocity_limit": {"LARM_JOINT0": 0.0}}, "velocity_limit"),
        ({"solver": "nosuch"}, "available"),
        ({"posture_target": "sideways"}, "home"),
        ({"position_cost": 0.0, "orientation_cost": 0.0}, "both 0"),
        ({"unknown_key": 1}, "Extra inputs"),
    ],
)
def test_config_rejects(kwargs: dict, message: str) -> None:
    with pytest.raises(pydantic.ValidationError, match=message):
        IKConfig(**kwargs)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"min_distance": -0.01}, "greater than or equal"),
        ({"detection_distance": 0.0}, "greater than"),
        ({"min_distance": 0.05, "detection_distance": 0.02}, "must exceed"),
        ({"extra": 1}, "Extra inputs"),
    ],
)
def test_collision_pair_rejects(kwargs: dict, message: str) -> None:
    with pytest.raises(pydantic.ValidationError, match=message):
        CollisionPairConfig(a="left_arm", b="table", **kwargs)


def test_config_is_frozen_and_yaml_ready() -> None:
    cfg = IKConfig.model_validate({"solver": "osqp", "collision_pairs": [{"a": "left_arm", "b": "table"}]})
    assert cfg.collision_pairs[0].min_distance == 0.005
    with pytest.raises(pydantic.ValidationError):
        cfg.dt = 1.0  # type: ignore[misc]
