"""The designer's HTTP side: the guard (:mod:`.guard`) put before every route of the
Bokeh server's Tornado application (a refused request answered 403, a login redirected
with its cookie), and optuna-dashboard started behind a guard of its own.
"""

from __future__ import annotations

import threading

from tornado.web import RequestHandler

from fuzzyservo.designer.guard import Guard, GuardedWSGI, Verdict
from fuzzyservo.errors import FuzzyservoError

_DASHBOARDS: dict[str, str] = {}
_DASH_LOCK = threading.Lock()


def start_dashboard(url: str, guard: Guard) -> str:
    """Start optuna-dashboard on ``url`` (once per URL, in this process) behind ``guard``'s
    hosts on its port with a token of its own, and return its address (with the token)."""
    try:
        import optuna_dashboard
    except ImportError:
        raise FuzzyservoError(
            "optuna-dashboard is not installed; pip install -e '.[dashboard]' and restart the designer"
        ) from None
    from wsgiref.simple_server import WSGIRequestHandler, make_server

    class Quiet(WSGIRequestHandler):
        def log_message(self, *args) -> None:  # no line per request on the designer's console
            pass

    with _DASH_LOCK:
        if url in _DASHBOARDS:
            return _DASHBOARDS[url]
        own = guard.with_port(guard.port + len(_DASHBOARDS))
        try:
            httpd = make_server(
                "127.0.0.1", own.port, GuardedWSGI(optuna_dashboard.wsgi(url), own),
                handler_class=Quiet,
            )  # fmt: skip
        except OSError as exc:
            raise FuzzyservoError(
                f"cannot start optuna-dashboard on 127.0.0.1:{own.port} ({exc.strerror or exc}); "
                "free that port or start the designer on another --port"
            ) from None
        threading.Thread(target=httpd.serve_forever, daemon=True).start()
        _DASHBOARDS[url] = own.url("127.0.0.1")
        return _DASHBOARDS[url]


class _Refused(RequestHandler):
    """The answer to a request the guard refuses (403, one line) or logs in (302 + cookie)."""

    def initialize(self, verdict: Verdict, guard: Guard) -> None:
        self.verdict = verdict
        self.guard = guard

    def prepare(self) -> None:
        if self.verdict.action == "login":
            self.set_header("Set-Cookie", self.guard.set_cookie())
            self.redirect(self.verdict.location)
            return
        self.set_status(403)
        self.set_header("Content-Type", "text/plain; charset=utf-8")
        self.finish(self.verdict.reason)


def install_guard(server, guard: Guard) -> None:
    """Put ``guard`` before every route of the designer's server: each HTTP request and
    websocket is checked (Host, Origin, token) before Bokeh or Panel sees it.

    Bokeh's server keeps its Tornado application in ``_tornado`` (Panel reads it the same
    way); its router is replaced by one that asks the guard first.
    """
    app = server._tornado
    find = app.find_handler

    def find_handler(request, **kwargs):
        verdict = guard.check(
            request.headers.get("Host"),
            request.headers.get("Origin"),
            request.path,
            request.query,
            request.headers.get("Cookie"),
        )
        if verdict.action == "pass":
            return find(request, **kwargs)
        return app.get_handler_delegate(request, _Refused, {"verdict": verdict, "guard": guard})

    app.find_handler = find_handler
