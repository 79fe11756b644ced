"""YAML-configured manipulation: config schema, phases and the runner behind ``nextage-qp run``."""

from nextage_qp.manipulation.config import ManipulationConfig, load_config

__all__ = ["ManipulationConfig", "load_config"]
