"""Tasks built on the simulator: the cooperative bar handover (:mod:`coopsim.tasks.handover`, run it with
``python -m coopsim.tasks.handover``) and its scene (:mod:`coopsim.tasks.scene`)."""
import importlib

from . import scene

__all__ = ["handover", "scene"]


def __getattr__(name):
    # imported on first use, so that ``python -m coopsim.tasks.handover`` runs it once, as __main__
    if name == "handover":
        return importlib.import_module(".handover", __name__)
    raise AttributeError(name)
