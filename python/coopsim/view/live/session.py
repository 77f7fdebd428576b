"""The live view's session: the server, the one thread that runs the simulation paced, the page's requests
queued to it, the run's start, end, failure and reset, the downloads, showing and closing."""
from __future__ import annotations

import contextlib
import math
import queue
import sys
import threading
import time
import weakref
from collections import deque
from typing import Callable, List, Optional

import numpy as np

from ...pacing import Pacer
from ...simulation import Simulation
from ..parts import robot_parts
from ..world import holding_now, robot_labels
from ... import _checks
from .common import _FOREVER, _GONE, _HOST, _robot_colors
from .data import _Data
from .drawing import Frame, _Drawing
from .panels import TAB_TITLES, _Panels
from . import serving


_VIEWS: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()   # simulation -> its open LiveView


def view_of(sim) -> Optional["LiveView"]:
    """The open live view of `sim`, or None."""
    try:
        v = _VIEWS.get(sim)
    except TypeError:       # not weak-referenceable: not a Simulation
        return None
    return v if v is not None and v.server is not None else None


class Restart(Exception):
    """Raised by :meth:`LiveView.run_to` (with ``restart=True``) when the page's Reset sent the run back to
    its start: the driver of a sequenced run catches it and runs its sequence again."""


class LiveView(_Panels, _Data, _Drawing):
    """A live page of a :class:`coopsim.Simulation`; made by :func:`live` (see there for the options).

    Attributes: ``url``, ``host``, ``port``; ``pacer`` (the :class:`coopsim.Pacer` that runs it: its speed
    and pause are what the page sets); ``server`` (the ``viser.ViserServer``); ``message`` (the last message
    shown in the panel, e.g. a refused value); ``error`` (an exception that stopped the run, or None);
    ``frames`` (frames sent); ``frame`` (the last :class:`Frame`).
    """

    def __init__(self, sim, *, t_end: Optional[float] = None, speed: float = 1.0, frame_rate: float = 40.0,
                 host: str = _HOST, port: int = 0, start: bool = True, collision_boxes: bool = False,
                 contact_lines: bool = True, ghosts: bool = True, labels: bool = False, holding: str = "shared",
                 history: float = 5.0, move_time: float = 1.0, resettable: bool = True,
                 url_prefix: Optional[str] = None,
                 title: Optional[str] = None, quiet: bool = False, paused: bool = False):
        if not isinstance(sim, Simulation):
            raise ValueError(f"sim must be a coopsim.Simulation, got {type(sim).__name__}")
        if t_end is not None:
            t_end = _checks.number(t_end, "t_end", text=True)
            if t_end < sim.time:
                raise ValueError(f"t_end must not be before the simulation's time {sim.time} s, got {t_end}")
        if not isinstance(host, str) or not host:
            raise ValueError(f"host must be a host name or address, got {host!r}")
        if not isinstance(port, (int, np.integer)) or isinstance(port, bool) or not 0 <= port <= 65535:
            raise ValueError(f"port must be 0 (any free port) .. 65535, got {port!r}")
        self._prefix = serving.url_prefix(url_prefix)      # checked before the server starts
        self.history = _checks.number(history, "history", text=True)
        if self.history <= 0:
            raise ValueError(f"history must be > 0 s, got {history!r}")
        self._move_time = self._check_move_time(move_time)
        other = view_of(sim)
        if other is not None:
            raise RuntimeError(f"this simulation already has a live view at {other.url}: use it "
                               f"(coopsim.view.live returns it) or close() it first")
        holding_now(sim, mode=holding)      # checks the mode
        self._holding_mode = holding
        try:
            import viser  # the optional live extra: only for a live view
        except ImportError:
            raise ImportError("coopsim.view.live needs viser: pip install 'coopsim[live]' "
                              "(scripts/setup.sh installs it)") from None

        self.sim = sim
        self.pacer = Pacer(speed=speed, frame_rate=frame_rate)
        self.t_end = t_end
        self.resettable = bool(resettable)
        self.robots = sim.robots
        self.labels = robot_labels(self.robots)
        self._references0 = sim.references
        self._dt = sim.dt
        self._control_every = sim.control_every
        self._show = dict(collision_boxes=bool(collision_boxes), contact_lines=bool(contact_lines),
                          ghosts=bool(ghosts), labels=bool(labels))
        self._queue: "queue.Queue[Callable[[], None]]" = queue.Queue()
        self._lock = threading.Lock()
        self._reset_pending = False
        self._closing = False
        self._thread: Optional[threading.Thread] = None
        self._driving = threading.RLock()    # held by the thread that runs the simulation now
        self.error: Optional[BaseException] = None
        self._finished = threading.Event()
        self._waiting = bool(paused)     # at the start, paused until Start (resume)
        if self._waiting:
            self.pacer.pause()
        self._clients_seen = 0
        self._outcome: Optional[tuple] = None    # ("finished" | "failed", text) of a run sequenced from Python
        self.rerun: Optional[Callable[[], None]] = None   # what Reset does after a sequenced run (its task again)
        self.stats: dict = {}
        self.message = ""
        self.frames = 0
        self.frame: Optional[Frame] = None
        self._changes = 0            # requests applied (a frame after one is drawn even if the time stands still)
        self._shown = None
        self._stats: deque = deque()
        self._hist: List[deque] = [deque() for _ in self.robots]
        self._last_plot = self._last_table = -math.inf
        self._plot_robot = 0
        self._table_robot = 0
        self._colors = [_robot_colors(r, i) for i, r in enumerate(self.robots)]
        self._parts = [robot_parts(r) for r in self.robots]      # the look (the boxes: on request)
        self._part_meshes: list = []
        self._ghost_meshes: list = []
        self._moving = [np.array([b.link != 0 for b in r.boxes], dtype=bool) for r in self.robots]
        self._world = sim.world
        self._free_names = [n for n in (self._world.body_names if self._world is not None else [])
                            if self._world.body(n)["kind"] == "free"]
        self._gizmos = {}

        # quiet (viser's banner dropped), a busy port refused, a host beyond loopback warned, the tab titled
        self.server = serving.start_server(viser, host, int(port), title or "coopsim live view")
        try:
            self.host, self.port = host, int(self.server.get_port())
            self.server.on_client_connect(lambda client: self._client_seen())
            self._build_scene()
            self._build_panels()
            self._draw(self._snapshot())
            serving.announce_readiness(self.server, TAB_TITLES)     # <html data-coopsim-live="ready">
        except BaseException:
            self.server.stop()
            raise
        _VIEWS[sim] = self
        if not quiet and not _in_notebook():
            print(f"coopsim live view: {self.url}", flush=True)
        if start:
            self.start(t_end)

    @property
    def url(self) -> str:
        """Where a browser opens the page: through the URL prefix when there is one (a remote Jupyter's
        proxy, e.g. ``/proxy/8123/``, relative to the Jupyter server), else :attr:`server_url`."""
        return serving.page_url(self._prefix, self.host, self.port)

    @property
    def server_url(self) -> str:
        """The server's own address, ``http://127.0.0.1:<port>`` by default (what a proxy forwards to)."""
        return serving.direct_url(self.host, self.port)

    def _check_open(self, what: str) -> None:
        if self.server is None or self._closing:
            raise RuntimeError(f"this live view is closed: {what} needs an open one "
                               f"(make another: cs.view.live(sim))")

    def show(self, height: int = 600) -> None:
        """In Jupyter, shows the live page in the cell (an iframe of :attr:`url`, height px, with its link);
        elsewhere prints the URL. Returns None (as a cell's last line it shows the page once). RuntimeError
        after :meth:`close`."""
        self._check_open("show()")
        if not isinstance(height, (int, np.integer)) or isinstance(height, bool) or height <= 0:
            raise ValueError(f"height must be a positive number of pixels, got {height!r}")
        if _in_notebook():
            from IPython.display import HTML, display  # only inside a notebook

            display(HTML(serving.frame_html(self.url, int(height), bool(self._prefix))))
            return None
        print(f"coopsim live view: {self.url}", flush=True)
        return None

    def _repr_html_(self) -> str:
        """The view as a cell's last value: the page in the cell (as :meth:`show`), or a line once closed."""
        if self.server is None or self._closing:
            return "<p>coopsim live view (closed)</p>"
        return serving.frame_html(self.url, 600, bool(self._prefix))

    def submit(self, fn: Callable[[], None]) -> None:
        """Queues fn() to run on the simulation's thread between chunks (a ValueError it raises is
        refused with a message in the panel)."""
        self._queue.put(fn)

    def call(self, fn: Callable, timeout: Optional[float] = 60.0):
        """fn() run on the simulation's thread between chunks (at once when nothing runs it); returns its
        value or raises its exception. For reading a running simulation consistently from another thread."""
        done = threading.Event()
        out = {}

        def go():
            try:
                out["value"] = fn()
            except BaseException as e:      # handed to the caller, not refused
                out["error"] = e
            done.set()
        if self._driving.acquire(blocking=False):      # nobody runs the simulation now
            try:
                go()
            finally:
                self._driving.release()
        else:
            self.submit(go)
            if not done.wait(timeout):
                raise TimeoutError(f"the simulation's thread did not answer in {timeout} s")
        if "error" in out:
            raise out["error"]
        return out.get("value")

    def set_speed_percent(self, value) -> None:
        """Sets the pacer's speed (0 .. 400 %), as the page's slider (refused in percent: the Run panel's)."""
        self._set_speed_percent(value)

    def pause(self) -> None:
        self.submit(self.pacer.pause)

    def resume(self) -> None:
        """Resumes the run at the speed set; at the start of a view made paused, starts it."""
        def go():
            self._waiting = False
            self.pacer.resume()
        self.submit(go)

    @property
    def run_state(self) -> str:
        """Where the run stands: 'waiting' (made paused, until Start), 'running', 'paused', 'finished' (its
        t_end reached, or its task done), 'failed' (an exception stopped it, or its task failed) or 'closed'."""
        if self.server is None:
            return "closed"
        if self.error is not None or (self._outcome is not None and self._outcome[0] == "failed"):
            return "failed"
        if self._finished.is_set() or self._outcome is not None:
            return "finished"
        if self._waiting:
            return "waiting"
        return "paused" if self.pacer.paused else "running"

    @property
    def outcome(self) -> Optional[str]:
        """The text the run's driver gave :meth:`finish` (e.g. a task's summary), or None."""
        return None if self._outcome is None else self._outcome[1]

    def say(self, text: str) -> None:
        """Shows `text` in the Run panel's message line (e.g. what a script driving the view is doing)."""
        self._say(str(text), "run")

    def finish(self, text: str, ok: bool = True) -> None:
        """For a run sequenced from Python (:meth:`run_to`): states that it is over, finished (ok) or failed,
        and shows `text` (e.g. the task's summary: each cycle's result, a failure's step, time and reason)
        in the Run panel. The page keeps serving (:meth:`serve`, :meth:`hold`)."""
        self._outcome = ("finished" if ok else "failed", str(text))
        md = getattr(self, "_outcome_md", None)
        if md is not None:
            head = "**Finished**" if ok else "**Failed**"
            # one line each, wrapped to the panel (a code block would hide their ends); markdown's own marks
            # in the text (e.g. '*' or '_' in a name) escaped
            lines = [_escape_markdown(line.strip()) for line in str(text).splitlines() if line.strip()]
            md.content = head + "\n\n" + "  \n".join(lines)
        self._changes += 1

    def one_step(self) -> None:
        """Pauses and advances one control period (control_every steps)."""
        def go():
            self.pacer.pause()
            self.sim.step(self._control_every)
        self.submit(go)

    def reset(self) -> None:
        """Back to t = 0, the initial states and the references the simulation had when the view was made.
        In a run sequenced from Python: :meth:`run_to` called with ``restart=True`` raises :class:`Restart`
        for its driver to start over, and after the run :meth:`serve` calls :attr:`rerun`."""
        if not self.resettable:
            self._say("Refused: this run is sequenced from Python and cannot go back to its start")
            return
        with self._lock:
            self._reset_pending = True

    def start(self, t_end: Optional[float] = None) -> None:
        """Runs the simulation paced in a thread of the view up to t_end (s; default the view's, else until
        closed), then keeps serving the page (and its requests) until :meth:`close`."""
        if self._thread is not None and self._thread.is_alive():
            raise RuntimeError("the live view is already running its simulation")
        t_end = self.t_end if t_end is None else _checks.number(t_end, "t_end", text=True)
        self._thread = threading.Thread(target=self._loop, args=(_FOREVER if t_end is None else t_end,),
                                        name="coopsim-live", daemon=True)
        self._thread.start()

    def run_to(self, t_end: float, *, restart: bool = False) -> None:
        """Runs the simulation paced up to t_end (s) in the calling thread (the simulation's thread), with
        the page live; returns at t_end, or at once if the page closed the view. For a run sequenced from
        Python (e.g. a task that plans phase by phase). An exception of the run shows in the panel and
        propagates. A view made paused waits at its start until the page's Start.

        restart: a Reset from the page sends the simulation back to its start (as :meth:`reset`) and raises
        :class:`Restart` here, for the driver to run its sequence again from its beginning; without it the
        run goes on from the start to t_end."""
        self._check_open("run_to()")
        t_end = _checks.number(t_end, "t_end", text=True)
        if self._thread is not None and self._thread.is_alive():
            raise RuntimeError("the live view runs its simulation in its own thread (start()); use wait()")
        with self._drive():
            self._outcome = None
            while not self._closing and self.sim.time < t_end - 0.5 * self._dt:
                try:
                    self.pacer.run(self.sim, t_end, on_frame=self._on_frame, keep_clock=True)
                except BaseException as e:
                    self._failed(e)
                    raise
                if self._reset_pending:
                    self._do_reset()
                    if restart:
                        raise Restart("the page sent the run back to its start")

    @contextlib.contextmanager
    def _drive(self):
        """The calling thread runs the simulation: the view's lock (the page's requests go to its queue) and
        the engine's hold of the run (another thread advancing it gets SimulationBusyError naming this view)."""
        with self._driving:
            driving = getattr(self.sim, "driving", None)
            if driving is None:
                yield
            else:
                with driving(f"the live view at {self.url}"):
                    yield

    def serve(self, seconds: float = math.inf, *, until_closed: Optional[float] = None) -> str:
        """Serves the page from the calling thread after a run sequenced from Python: the page's requests
        (gains, teach moves, one step, downloads, Reset: :attr:`rerun` when set, else back to the start) are
        applied and the scene drawn, for `seconds` s of wall time, until :meth:`close`, or until every page
        has been gone for `until_closed` s (None: never). Returns why it ended: 'time', 'closed' or
        'pages gone'."""
        period = 1.0 / self.pacer.frame_rate
        end = time.monotonic() + seconds
        gone_since = None
        with self._drive():
            while True:
                if self._closing or self.server is None:
                    return "closed"
                if time.monotonic() >= end:
                    return "time"
                if until_closed is not None:
                    if self.server.get_clients():
                        gone_since = None
                    elif self.pages_seen and gone_since is None:
                        gone_since = time.monotonic()
                    elif gone_since is not None and time.monotonic() - gone_since >= until_closed:
                        return "pages gone"
                if self._reset_pending:
                    if self.rerun is not None:
                        self._do_reset()
                        self._run_again()
                        continue
                    self._do_reset()
                try:
                    self._on_frame(self.sim, self.pacer)
                except BaseException as e:
                    self._failed(e)
                    raise
                time.sleep(period)

    def _client_seen(self) -> None:
        self._clients_seen += 1

    @property
    def pages_seen(self) -> int:
        """How many pages (browser connections) have connected to the view so far."""
        return self._clients_seen

    def _run_again(self) -> None:
        """Reset after a sequenced run: its driver's :attr:`rerun` (the task again, in this thread); a
        Reset during it starts it over."""
        while True:
            self._outcome = None
            try:
                self.rerun()
                return
            except Restart:
                continue

    def wait(self, timeout: Optional[float] = None) -> bool:
        """Waits until the view's run reaches its t_end (or timeout s); re-raises the exception that
        stopped it. Returns True when the run is over."""
        end = None if timeout is None else time.monotonic() + timeout
        while True:
            if self.error is not None:
                raise self.error
            if self._finished.is_set():
                return True
            if end is not None and time.monotonic() >= end:
                return False
            time.sleep(0.02)

    def _loop(self, t_end: float) -> None:
        with self._drive():
            while not self._closing:
                if self._reset_pending:
                    self._do_reset()
                    self._finished.clear()
                if self.error is None and self.sim.time < t_end - 0.5 * self._dt:
                    try:
                        self.pacer.run(self.sim, t_end, on_frame=self._on_frame)
                    except BaseException as e:
                        self._failed(e)
                else:
                    if self.sim.time >= t_end - 0.5 * self._dt:
                        self._finished.set()
                    try:
                        self._on_frame(self.sim, self.pacer)
                    except BaseException as e:
                        self._failed(e)
                        return
                    time.sleep(1.0 / self.pacer.frame_rate)

    def _failed(self, e: BaseException) -> None:
        if isinstance(e, (Restart, KeyboardInterrupt)):
            return
        self.error = e
        try:
            self._say(f"Run stopped: {type(e).__name__}: {e}")
        except Exception:      # pragma: no cover - the server may be gone
            pass

    def _do_reset(self) -> None:
        with self._lock:
            self._reset_pending = False
        self.sim.reset()
        for i, ref in enumerate(self._references0):
            self.sim.set_reference(i, ref)
        self.error = None
        self._changes += 1
        for h in self._hist:
            h.clear()
        self._stats.clear()
        self._say("Reset to the start")

    def _on_frame(self, sim, pacer):
        """The pacer's frame hook, on the simulation's thread: apply the page's requests, then draw."""
        while True:
            try:
                fn = self._queue.get_nowait()
            except queue.Empty:
                break
            self._changes += 1
            try:
                fn()
            except ValueError as e:          # IKError is a ValueError
                self._say(f"Refused: {e}")
        if self._closing or self._reset_pending:
            return False
        self._draw(self._snapshot())
        return None

    def hold(self, seconds: Optional[float] = None, *, until_closed: Optional[float] = _GONE) -> str:
        """Keeps serving the page (:meth:`serve`: requests applied, downloads, Reset runs again) for `seconds`
        (None: until Ctrl-C when run from a terminal, else not at all), or until every page has been closed
        for `until_closed` s (None: pages may come and go), then closes the view. For a script whose run is
        over but whose page should stay. Returns why it ended: 'time', 'closed', 'pages gone' or 'Ctrl-C'."""
        if seconds is None:
            seconds = math.inf if sys.stdout.isatty() else 0.0
        why = "time"
        try:
            if seconds > 0 and self.server is not None:
                print(f"the live page stays at {self.url}: Ctrl-C (or closing the page) to stop", flush=True)
                why = self.serve(seconds, until_closed=until_closed)
        except KeyboardInterrupt:
            why = "Ctrl-C"
        finally:
            self.close()
        return why

    def close(self) -> None:
        """Stops the run (between chunks) and the server, and frees the port."""
        if self._closing and self.server is None:
            return
        self._closing = True
        self.pacer.stop()
        th = self._thread
        if th is not None and th is not threading.current_thread():
            th.join(timeout=30)
        with self._driving:         # a run_to in progress ends at its next frame
            pass
        if self.server is not None:
            self.server.stop()
            self.server = None
        if _VIEWS.get(self.sim) is self:
            del _VIEWS[self.sim]

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def __repr__(self) -> str:
        return f"<coopsim.view.LiveView {self.url} t={self.sim.time:.4g} s, {self.frames} frames>"

def _escape_markdown(text: str) -> str:
    """Text shown as itself in markdown (its marks backslash-escaped)."""
    return "".join("\\" + c if c in "\\`*_{}[]<>()#+-.!|" else c for c in text)


def _in_notebook() -> bool:
    ip = sys.modules.get("IPython")
    if ip is None:
        return False
    try:
        shell = ip.get_ipython()
    except Exception:      # pragma: no cover
        return False
    return shell is not None and type(shell).__name__ == "ZMQInteractiveShell"
