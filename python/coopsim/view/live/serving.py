"""Where the live page is served and how a browser reaches it: viser's server started quiet, its port and host
checked, the page's address through a proxy (a remote Jupyter: jupyter-server-proxy), the tab's title, the
page's readiness (an attribute of its <html> a script or a test waits on), and the page in a notebook cell."""
from __future__ import annotations

import html
import importlib.util
import ipaddress
import json
import os
import re
import threading
import warnings
import weakref
from typing import Optional

#: The environment variable read when ``live(sim, url_prefix=...)`` is not given: the page's address as a
#: browser reaches it, ``{port}`` standing for the server's port, e.g. ``/proxy/{port}/`` (jupyter-server-proxy
#: on the Jupyter server the notebook came from) or ``https://hub.example.org/user/me/proxy/{port}/``.
ENV_PREFIX = "COOPSIM_LIVE_URL_PREFIX"

_LOOPBACK_NAMES = ("localhost", "localhost.localdomain", "ip6-localhost")

# threads whose rich.print is dropped: a live view's server thread (viser's "Server stopped") and a thread
# while it starts a server (viser's banner); a WeakSet of Thread objects (an ident can be reused)
_MUTED: "weakref.WeakSet[threading.Thread]" = weakref.WeakSet()
_MUTE_LOCK = threading.Lock()


def _mute_viser() -> None:
    """Wraps rich.print (which viser prints through, in a notebook as cell output) once so that it drops
    what the threads in _MUTED print; every other thread prints as before."""
    import rich  # viser's own printer (the live extra), loaded with viser

    with _MUTE_LOCK:
        if getattr(rich.print, "_coopsim_muted", False):
            return
        original = rich.print

        def quiet_print(*args, **kwargs):
            if threading.current_thread() in _MUTED:
                return None
            return original(*args, **kwargs)
        quiet_print._coopsim_muted = True
        quiet_print.__doc__ = original.__doc__
        rich.print = quiet_print


def is_loopback(host: str) -> bool:
    """Whether `host` (a name or an address) is this machine only (127.0.0.0/8, ::1, localhost)."""
    if host.lower() in _LOOPBACK_NAMES:
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False


def start_server(viser, host: str, port: int, title: str):
    """A viser server on host:port (port 0: any free one), printing nothing (its banner and its "Server
    stopped" dropped), its page titled `title`. A busy port is refused (viser would move on to the next
    one without a word): ValueError naming it. A host other than this machine's loopback warns (UserWarning)
    that the page has no authentication."""
    if not is_loopback(host):
        warnings.warn(f"host={host!r}: the live page has no authentication: anyone who can reach this machine "
                      f"on its port can watch and steer the run (keep the default 127.0.0.1 and use an SSH "
                      f"tunnel or Jupyter's proxy: url_prefix)", UserWarning, stacklevel=4)
    _mute_viser()
    me = threading.current_thread()
    _MUTED.add(me)
    try:
        server = viser.ViserServer(host=host, port=int(port), label=title, verbose=False)
    finally:
        _MUTED.discard(me)
    thread = getattr(getattr(server, "_websock_server", None), "_server_thread", None)
    if thread is not None:
        _MUTED.add(thread)
    got = int(server.get_port())
    if port and got != port:
        server.stop()
        raise ValueError(f"port {port} is in use on {host} (another program or live view): give another port, "
                         f"or port=0 for any free one")
    set_title(server, title)
    return server


def set_title(server, title: str) -> None:
    """Sets the browser tab's title of every page of `server`, those open and those to come (viser's page is
    titled "Viser"; a script message run by each page as it connects)."""
    from viser import _messages  # viser's message of a script to run in the page

    server.gui._websock_interface.queue_message(
        _messages.RunJavascriptMessage(source=f"document.title = {json.dumps(str(title))};"))


#: The attribute of the page's ``<html>`` element that states whether the page takes input (see
#: :func:`announce_readiness`): ``"ready"`` or ``"connecting"``.
READY_ATTRIBUTE = "data-coopsim-live"

_READINESS_JS = """(() => {
  const tabs = %s, root = document.documentElement;
  const live = window.coopsimLive || (window.coopsimLive = {state: "", ready: false, changes: 0});
  live.tabs = tabs;
  if (live.timer !== undefined) return;          /* a reconnect replays this script: one watcher a page */
  let epoch = 0, asked = -1, drawn = -1;        /* epoch: a new one each time the tabs are not there */
  const set = (state) => {
    if (live.state === state) return;
    live.state = state; live.ready = state === "ready"; live.changes += 1;
    root.setAttribute(%s, state);
  };
  /* each tab in the page and taking pointer input (viser freezes its panel while the websocket is closed) */
  const built = () => {
    const there = Array.from(document.querySelectorAll('[role="tab"]'))
      .filter((t) => getComputedStyle(t).pointerEvents !== "none").map((t) => t.textContent.trim());
    return live.tabs.every((name) => there.includes(name));
  };
  /* ready: the tabs built and two frames drawn since (the page's first frames may take seconds) */
  const check = () => {
    if (!built()) { epoch += 1; set("connecting"); return; }
    if (drawn === epoch) { set("ready"); return; }
    if (asked === epoch) return;
    const e = asked = epoch;
    requestAnimationFrame(() => requestAnimationFrame(() => { if (e === epoch) { drawn = e; check(); } }));
  };
  set("connecting");
  live.timer = setInterval(check, 100);
  check();
})();"""


def announce_readiness(server, tabs) -> None:
    """Makes every page of `server` state whether it takes input, for a script or a test to wait on (a
    loaded machine may take many seconds to build the panel and draw its first frames). A script queued
    after the panels and the first frame (so each page runs it once it has received them, and again on
    each reconnect's replay) keeps the page's ``<html data-coopsim-live="...">`` and
    ``window.coopsimLive`` (``state``, ``ready``, ``tabs``, ``changes``) up to date, every 0.1 s:
    ``"ready"`` once each tab named in `tabs` is in the page and takes pointer input (viser freezes the
    panel while its websocket is closed: a connected page) and the page has drawn two animation frames
    since; ``"connecting"`` before, and again while the page is disconnected."""
    from viser import _messages  # viser's message of a script to run in the page

    source = _READINESS_JS % (json.dumps([str(t) for t in tabs]), json.dumps(READY_ATTRIBUTE))
    server.gui._websock_interface.queue_message(_messages.RunJavascriptMessage(source=source))


def url_prefix(value: Optional[str]) -> str:
    """The page's address template as a browser reaches it ('' for the server's own address): `value`, else
    the environment's COOPSIM_LIVE_URL_PREFIX, else 'jupyter' when this runs under JupyterHub
    (JUPYTERHUB_SERVICE_PREFIX set) with jupyter-server-proxy installed, else ''. 'jupyter' stands for
    ``<JUPYTERHUB_SERVICE_PREFIX or />proxy/{port}/``. A template is a path from the Jupyter server's root
    ('/proxy/{port}/') or a full http(s) URL; ValueError naming url_prefix otherwise."""
    where = "url_prefix"
    if value is None:
        value = os.environ.get(ENV_PREFIX)
        where = ENV_PREFIX
        if value is None:
            value = "jupyter" if os.environ.get("JUPYTERHUB_SERVICE_PREFIX") and _has_server_proxy() else ""
    if not isinstance(value, str):
        raise ValueError(f"url_prefix must be a text such as '/proxy/{{port}}/' or 'jupyter', got {value!r}")
    value = value.strip()
    if value == "":
        return ""
    if value == "jupyter":
        base = os.environ.get("JUPYTERHUB_SERVICE_PREFIX", "/") or "/"
        value = base.rstrip("/") + "/proxy/{port}/"
    if not (value.startswith("/") or re.match(r"https?://[^/]+", value)):
        raise ValueError(f"{where} must be a path such as '/proxy/{{port}}/', an http(s) URL or 'jupyter', "
                         f"got {value!r}")
    if any(c in value for c in "?#\"'<> "):
        raise ValueError(f"{where} must be a plain path or URL (no ?, #, quotes, <, > or spaces), got {value!r}")
    try:
        value.format(port=0)
    except (KeyError, IndexError, ValueError):
        raise ValueError(f"{where} may hold only {{port}} in braces, got {value!r}") from None
    return value if value.endswith("/") else value + "/"


def _has_server_proxy() -> bool:
    return importlib.util.find_spec("jupyter_server_proxy") is not None


def direct_url(host: str, port: int) -> str:
    """The server's own address (a wildcard host as the loopback a local browser uses)."""
    h = "127.0.0.1" if host in ("0.0.0.0", "") else "[::1]" if host == "::" else \
        f"[{host}]" if ":" in host and not host.startswith("[") else host
    return f"http://{h}:{port}"


def page_url(prefix: str, host: str, port: int) -> str:
    """Where a browser opens the page: the prefix with its {port}, or the server's own address."""
    return prefix.format(port=port) if prefix else direct_url(host, port)


def frame_html(url: str, height: int, proxied: bool) -> str:
    """The page in a notebook cell: an iframe of `url`, its link, and (served directly, not through a proxy)
    a one-line note for a remote Jupyter, whose browser cannot reach this machine's 127.0.0.1."""
    u = html.escape(url, quote=True)
    note = "" if proxied else (
        " &mdash; a blank frame? The page is served on the kernel's machine; a remote Jupyter reaches it "
        "only through its proxy: <code>cs.view.live(sim, url_prefix=\"jupyter\")</code> (jupyter-server-proxy) "
        "or the environment's <code>COOPSIM_LIVE_URL_PREFIX</code> (docs/views.md)")
    return (f'<iframe src="{u}" width="100%" height="{int(height)}" style="border:none"></iframe>'
            f'<p style="font-size:smaller">coopsim live view: <a href="{u}" target="_blank">{u}</a>{note}</p>')
