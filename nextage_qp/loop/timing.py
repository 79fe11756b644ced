"""Loop rates of the simulation: the physics step and the control period."""

from __future__ import annotations

from pydantic import Field, model_validator

from nextage_qp.io.schema import YamlModel


class Timing(YamlModel):
    """Loop rates: the physics step and the control period (a whole multiple of it)."""

    sim_dt: float = Field(default=0.001, ge=1e-5, le=0.01, description="Physics step [s], 10 us to 10 ms.")
    ctrl_dt: float = Field(default=0.004, gt=0, le=0.05, description="IK + Ruckig period [s] (multiple of sim_dt).")

    @model_validator(mode="after")
    def _multiple(self) -> Timing:
        ratio = self.ctrl_dt / self.sim_dt
        if abs(ratio - round(ratio)) > 1e-9 or round(ratio) < 1:
            raise ValueError(f"ctrl_dt ({self.ctrl_dt} s) must be a whole multiple of sim_dt ({self.sim_dt} s)")
        return self

    @property
    def n_substeps(self) -> int:
        """Physics steps per control period."""
        return round(self.ctrl_dt / self.sim_dt)
