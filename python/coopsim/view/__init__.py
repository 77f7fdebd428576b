"""Seeing it: robots as shaded boxes in matplotlib, still (:func:`draw`) or animated from a log (:func:`animate`).

The paper's colour conventions (:data:`COLORS`): the desired pose as a
transparent blue ghost, robots green while both hold a body (holding='any': while they hold anything), collision
boxes green (free) or red (in contact), contact points as red lines along
the normal, the bar (any extra :class:`Body`) red.

    scene = view.draw(None, [r1, r2], [q1, q2], reference=[q1_ref, None])
    scene.update([q1_new, q2_new])              # cheap: one polygon collection changes
    view.animate(log, sim.robots, fps=30, speed=2.0, path="out/run.mp4")   # or .gif; or show inline

With a Bullet world (:mod:`coopsim.view.world`): its static boxes drawn as grey scenery, its free
bodies (the bar red) at their logged poses, and with ``collision_boxes=True`` the colliding boxes red
and the contact points red lines, all from the simulation:

    view.draw(None, sim, collision_boxes=True)        # the robots, the world and its contacts now
    view.animate(sim, collision_boxes=True)           # the whole run, from its log
"""
from .animation import Animation, animate, ffmpeg_path
from .geometry import box_corners, box_faces
from .live import LiveView, live
from .replay import replay_html
from .scene import COLORS, Body, Scene, draw
from .world import colliding_from_log, contacts_from_log, world_bodies
from .world import holding_from_log, holding_now

__all__ = ["COLORS", "Animation", "Body", "Scene", "animate", "box_corners", "box_faces", "draw", "ffmpeg_path"]
__all__ += ["colliding_from_log", "contacts_from_log", "world_bodies"]
__all__ += ["replay_html"]
__all__ += ["holding_from_log", "holding_now"]
__all__ += ["LiveView", "live"]
