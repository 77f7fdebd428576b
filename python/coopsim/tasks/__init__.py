"""Tasks built on the simulator: the cooperative bar handover (:mod:`coopsim.tasks.handover`, run it with
``python -m coopsim.tasks.handover``; :class:`TaskRun`, one run of it as an item of :func:`coopsim.sweep`)
and its scene (:mod:`coopsim.tasks.scene`); the dual carry, both SCARAs carrying one bar
(:mod:`coopsim.tasks.carry`, ``python -m coopsim.tasks.carry``)."""
from . import carry, handover, scene
from .handover import TaskRun

__all__ = ["TaskRun", "carry", "handover", "scene"]
