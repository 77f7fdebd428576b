"""A live view of a running simulation in the browser (and in a notebook cell): the paper's graphic interface.

    v = cs.view.live(sim, t_end=10.0)     # serves http://127.0.0.1:<port>, runs the simulation paced at 100 %
    v.show()                              # in Jupyter: the page in the cell (an IFrame); in a script: the URL
    v.wait()                              # until t_end (re-raises an exception of the run)
    v.close()                             # stops the server, frees the port

The page (served by ``viser``, the ``live`` extra: ``pip install coopsim[live]``) shows every robot as its
parts (:mod:`coopsim.view.parts`: the SCARAs as the paper draws them, a URDF arm with its visual meshes,
another robot as its boxes), placed on the link frames (``Robot.frames(q)``, one call per robot and frame),
the desired pose as a transparent blue ghost of the moving links' parts, the robots green while they hold a
body together, the world's scenery (grey), its free bodies (the bar red) and the floor, with the colours of
:data:`coopsim.view.COLORS`; with "Collision boxes" on, the link boxes (``Robot.shapes(q)``) instead of the
parts, green (free) or red (in contact), and the contact points as red lines.

Panels (tabs): **Run**: speed 0-400 %, pause, resume, one step (one control period), reset to the start,
and the time supervision (simulated and wall time, set and achieved speed, step time mean and max,
frames per second). **Display**: collision boxes, contact lines, ghosts, labels, camera views.
**Robots**: per robot its controller and its gains (editable), its dimensions (editable for the built-in
SCARAs), and a teach mode: joint sliders, a joint target typed in, and a gizmo at the clamp; a target
becomes a cubic from where the robot is (its measured q and qd now) to the target (closed-form IK
``robot.ik`` for the gizmo) as the robot's new reference. **Plots**: a chosen robot's joint positions
against their references and its tracking error over the last seconds. **Data**: the last rows of the
log; the log as CSV or Excel to download.

One writer: the simulation runs paced (:class:`coopsim.Pacer`, the engine stepping with the GIL
released) in one thread, the view's or the caller's (:meth:`LiveView.run_to`). What the page asks for is
queued and applied by that thread between chunks (the pacer's frame hook), where it also takes the
frame's snapshot. A value from the page passes the checks of the API it calls (the pacer's speed,
``CubicTrajectory``, ``Robot.ik``, the joint limits); a bad one is refused with a message in the panel and
the run goes on. Pages may come, go and reconnect; the run does not notice. The server binds 127.0.0.1
unless another host is given, and never opens viser's share tunnel.

Gains typed in and set (:meth:`LiveView.set_gains`) build a new controller of the same kind (``PID`` or
``ComputedTorque``, its other settings kept) that replaces the robot's through ``Simulation.set_controller``
from the next control step; a PID's integral restarts at zero. The constructor and ``set_controller`` check
the values (>= 0, finite, 1 or n of them). A Python controller's gains are its own: shown by name only. A
built-in SCARA's L1, L2 and base height typed in and set (:meth:`LiveView.set_dimensions`) rebuild it by its
maker (``cs.robots.scara1``/``scara2``) and replace it through ``Simulation.set_robot``, the run going on from
the same state; another robot's dimensions are shown without editing. "Reset to the start" keeps the gains
and dimensions last set.
"""
from __future__ import annotations

from typing import Optional

from .common import _HOST, _rotation, quaternions  # noqa: F401  (quaternions, _rotation: checked by the tests)
from .drawing import Frame
from .session import LiveView, Restart, _in_notebook, view_of  # noqa: F401

__all__ = ["Frame", "LiveView", "Restart", "live"]


def live(sim, *, t_end: Optional[float] = None, speed: float = 1.0, frame_rate: float = 40.0, host: str = _HOST,
         port: int = 0, start: bool = True, collision_boxes: bool = False, contact_lines: bool = True,
         ghosts: bool = True, labels: bool = False, holding: str = "shared", history: float = 5.0,
         move_time: float = 1.0, resettable: bool = True, title: Optional[str] = None,
         url_prefix: Optional[str] = None,
         quiet: bool = False, paused: bool = False) -> LiveView:
    """A live view of `sim` (any :class:`coopsim.Simulation`: one or several robots, with or without a
    world) in the browser; returns the :class:`LiveView`.

    t_end: simulated time (s) the run goes to (None: until closed; the log grows meanwhile). speed: 0 .. 4
    (400 %). frame_rate: frames per second (Hz) the view aims at (the pacer sleeps to it; 40 reaches 30 or
    more). host, port: where the server listens (127.0.0.1 by default, port 0: any free one; a busy port
    is refused with a ValueError; another host only on purpose: it warns, the page has no
    authentication). start: run at once in
    the view's thread (False: call :meth:`LiveView.start`, or drive it with :meth:`LiveView.run_to`).
    collision_boxes, contact_lines, ghosts, labels: what the Display panel shows at first. holding:
    'shared' (robots green while another robot holds the same body) or 'any'. history: seconds shown in the
    plots. move_time: duration (s) of a teach move. resettable: whether the page may reset the run to its
    start (False for a run sequenced from Python). quiet: print nothing (the URL is not printed; viser's
    banner never is). url_prefix: the page's address as the browser reaches it, for a remote Jupyter whose
    browser cannot reach this machine's 127.0.0.1: a path from the Jupyter server's root with ``{port}``
    for the server's port (``'/proxy/{port}/'``: jupyter-server-proxy), a full http(s) URL, or ``'jupyter'``
    (``<JUPYTERHUB_SERVICE_PREFIX or />proxy/{port}/``); None: the environment's COOPSIM_LIVE_URL_PREFIX,
    else ``'jupyter'`` under JupyterHub with jupyter-server-proxy installed, else the server's own address
    (``''``). title: the page's title (its tab and panel; default "coopsim live view"). paused: wait at the start,
    paused, until the page's Start (or :meth:`LiveView.resume`).

    One view per simulation: while `sim` has an open view (a notebook cell run again), this returns that
    view as it is (the options given here are not applied; :meth:`LiveView.close` it for a new one). One
    driver per run: the view's thread holds the run, and another thread advancing or changing it meanwhile
    gets :class:`coopsim.SimulationBusyError` naming the view.
    """
    existing = view_of(sim)
    if existing is not None:
        if not quiet:
            print(f"coopsim live view: this simulation's page is already at {existing.url} (the same view; "
                  f"close() it for a new one)", flush=True)
        return existing
    return LiveView(sim, t_end=t_end, speed=speed, frame_rate=frame_rate, host=host, port=port, start=start,
                    collision_boxes=collision_boxes, contact_lines=contact_lines, ghosts=ghosts, labels=labels,
                    holding=holding, history=history, move_time=move_time, resettable=resettable,
                    url_prefix=url_prefix, title=title,
                    quiet=quiet, paused=paused)

