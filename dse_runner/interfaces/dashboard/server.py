"""The live dashboard's server: the page (page.py) served by Bokeh from a background thread, beside Dask's own
dashboard, until stopped with a farewell.

One server shows a sweep running in this process (``submit`` starts it), one running elsewhere
(``dse-runner dashboard RESULTS``) and a finished one: the feed reads only the store. dask_link.py adds a
"dse-runner" page to Dask's dashboard that redirects here.
"""

from __future__ import annotations

import asyncio
import socket
import threading
import time
from dataclasses import dataclass
from functools import partial
from typing import Any

from ...errors import DseError
from ...sweeps import store
from ...sweeps.spec import Space
from .feed import Feed
from .page import Page


def parse_address(text: str) -> tuple[str, int]:
    """``host:port`` (port 0 for any free one) -> (host, port)."""
    host, colon, port = text.rpartition(":")
    if not colon or not host or not port.isdigit():
        raise DseError(
            f"dashboard address {text!r}: expected host:port, e.g. 127.0.0.1:8790 (port 0 for any)"
        )
    return host, int(port)


def _free_port(host: str) -> int:
    with socket.socket(socket.AF_INET6 if ":" in host else socket.AF_INET) as s:
        s.bind((host, 0))
        return s.getsockname()[1]


def _origins(host: str, port: int) -> list[str]:
    """Pages whose websocket Bokeh accepts: the names a browser may use for this address."""
    names = {host, "localhost", "127.0.0.1"}
    if host not in ("127.0.0.1", "localhost", "::1"):
        names |= {socket.gethostname(), socket.getfqdn()}
    return sorted(f"{name}:{port}" for name in names)


FAREWELL_SECONDS = 10.0  # at most this long for the open pages to take their last update
PREPARING_SECONDS = 120.0  # at most this long, when stopping, for the pages' views being prepared to end
DELIVERY_SECONDS = 2.0  # then this long for it to leave the server (0.5 s lost it under a full machine)


@dataclass
class DashboardServer:
    """A dashboard served from a background thread; ``stop()`` ends it."""

    url: str
    _loop: Any
    _thread: threading.Thread
    feed: Feed | None = None

    def stop(self, farewell: str | None = None) -> None:
        """Stop serving. With ``farewell``, every open page first shows the sweep's final state and figures
        and the note, and is told the connection's end is meant: no lost-connection banner, no error."""
        if farewell is not None and self.feed is not None:
            told = []
            for page in list(self.feed.pages):
                said = threading.Event()
                page.doc.add_next_tick_callback(partial(page.finish, farewell, said))
                told.append(said)
            deadline = time.monotonic() + FAREWELL_SECONDS  # every page its chance, however slow one is
            if [said.wait(max(0.0, deadline - time.monotonic())) for said in told].count(True):
                time.sleep(DELIVERY_SECONDS)
        self._loop.add_callback(self._loop.stop)
        self._thread.join(timeout=10)
        deadline = time.monotonic() + PREPARING_SECONDS  # a page's view being prepared (the best point's
        for page in list(self.feed.pages if self.feed is not None else ()):  # track simulated) ends first, so
            page.join(max(0.0, deadline - time.monotonic()))  # nothing of it outlives the server


def serve(
    output: store.Root, sweep: str, address: str = "127.0.0.1:0", space: Space | None = None
) -> DashboardServer:
    """Serve the dashboard of ``sweep`` in ``output`` at ``address`` (loopback by default: the page
    shows file paths and has no login) from a daemon thread."""
    from bokeh.application import Application
    from bokeh.application.handlers.function import FunctionHandler
    from bokeh.server.server import Server
    from tornado.ioloop import IOLoop

    host, port = parse_address(address)
    try:
        port = port or _free_port(host)
    except OSError as e:
        raise DseError(f"dashboard address {address}: {e.strerror}") from None
    feed = Feed(output, sweep, space)
    feed.warm()
    ready: dict[str, Any] = {}
    started = threading.Event()

    def run() -> None:
        asyncio.set_event_loop(asyncio.new_event_loop())
        loop = IOLoop.current()
        try:
            server = Server(
                {"/": Application(FunctionHandler(partial(Page, feed)))},
                io_loop=loop,
                address=host,
                port=port,
                allow_websocket_origin=_origins(host, port),
            )
            server.start()
        except OSError as e:
            ready["error"] = e
            started.set()
            return
        ready["loop"] = loop
        started.set()
        loop.start()
        server.stop()

    thread = threading.Thread(target=run, name="dse-runner-dashboard", daemon=True)
    thread.start()
    started.wait()
    if "error" in ready:
        raise DseError(f"cannot serve the dashboard at {host}:{port}: {ready['error'].strerror}")
    shown = f"[{host}]" if ":" in host else host
    return DashboardServer(f"http://{shown}:{port}/", ready["loop"], thread, feed)


def farewell(output: store.Root, how: str) -> str:
    """What a page says when its server stops: how, and how to see the results again."""
    return (
        f"{how} This page shows the final state, and no longer updates. To open the results again: "
        f"dse-runner dashboard {output}"
    )
