"""Tasks built on the simulator: the cooperative bar handover's scene (:mod:`coopsim.tasks.scene`)."""
from . import scene

__all__ = ["scene"]
