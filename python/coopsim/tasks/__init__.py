"""Tasks built on the simulator: the cooperative bar handover (:mod:`coopsim.tasks.handover`, run it with
``python -m coopsim.tasks.handover``; :class:`TaskRun`, one run of it as an item of :func:`coopsim.sweep`)
and its scene (:mod:`coopsim.tasks.scene`)."""
from . import handover, scene
from .handover import TaskRun

__all__ = ["TaskRun", "handover", "scene"]
