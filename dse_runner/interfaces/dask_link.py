"""A "dse-runner" page on Dask's dashboard that redirects to ours: a scheduler plugin, the way distributed
extends itself. Apart from dashboard/, so that a page over a store (the dashboard and report commands)
does not import Dask's distributed; the scheduler imports this module to run the plugin."""

from __future__ import annotations

from distributed.diagnostics.plugin import SchedulerPlugin

DASK_PAGE = "dse-runner"  # the page added to Dask's dashboard

_TARGET: dict[str, str] = {}  # in the scheduler's process: where its dse-runner page redirects


class DaskLink(SchedulerPlugin):
    """Adds a "dse-runner" page to Dask's dashboard that redirects to our dashboard."""

    name = "dse-runner-dashboard"

    def __init__(self, url: str):
        self.url = url

    async def start(self, scheduler) -> None:
        from tornado import web

        first = not _TARGET
        _TARGET["url"] = self.url
        app = getattr(scheduler, "http_application", None)
        if app is None or not first:
            return

        class Redirect(web.RequestHandler):
            def get(self) -> None:
                self.redirect(_TARGET["url"])

        app.add_handlers(r".*", [(rf"/{DASK_PAGE}/?", Redirect)])
        try:  # the link in the navigation bar of Dask's own pages
            from distributed.dashboard.scheduler import template_variables

            pages = template_variables(scheduler)["pages"]
            if DASK_PAGE not in pages:
                pages.append(DASK_PAGE)
        except ImportError:  # no bokeh on the scheduler: no Dask pages to link from
            pass


def link_from_dask(client, url: str) -> str | None:
    """Make Dask's dashboard link to ``url``; the address of the linking page, or None if the
    scheduler cannot take the plugin (no dse-runner installed beside it, say)."""
    try:
        client.register_plugin(DaskLink(url))
    except Exception:  # noqa: BLE001  (the scheduler could not take it: the link is a convenience)
        return None
    dask = client.dashboard_link
    return dask.rsplit("/", 1)[0] + f"/{DASK_PAGE}" if dask else None
