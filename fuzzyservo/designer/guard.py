"""Who may drive the designer: a local page that knows this launch's token, nobody else.

A web app on ``127.0.0.1`` is reachable by every page the user's browser opens. Two
checks keep foreign pages out, and both run on every HTTP request and websocket before
the web framework sees it (:func:`fuzzyservo.designer.app.run_server` installs them on
the designer's server, :class:`GuardedWSGI` on the optuna-dashboard it starts):

- **Host and Origin.** The ``Host`` header must name an allowed host (``127.0.0.1``,
  ``localhost``, ``[::1]``, the address the server is bound to, or one given with
  ``--allow-host``) on the server's own port. A DNS-rebinding page reaches the server
  under its own name (``Host: evil.example:5006``) and is refused. An ``Origin``
  header, which browsers send with websockets and with every request a script makes,
  must be one of those hosts on that port: another site's page is refused even when
  it names the right host.
- **A token per launch.** The address the command prints carries a random token
  (``?token=...``). The first request with it gets the token as a cookie (``HttpOnly``,
  ``SameSite=Strict``: a browser sends it only with the designer's own requests) and is
  sent on to the address without it; every request must carry it. Another user of the
  machine, or a page that guesses the port, has neither.

No web framework is imported here: the checks are functions of the headers, tested on
their own (``tests/security/``).
"""

from __future__ import annotations

import hmac
import secrets
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from http.cookies import CookieError, SimpleCookie
from typing import Any
from urllib.parse import parse_qs, urlsplit

#: hosts a local page reaches the designer by (host names, lower case, no port)
LOOPBACK = ("127.0.0.1", "localhost", "[::1]")
#: what a refused request reads (the status is 403)
REFUSED_HOST = "forbidden: this address is not the designer's (Host {host!r}); open the address `fuzzyservo designer` printed, or start it with --allow-host NAME"
REFUSED_ORIGIN = (
    "forbidden: a page from another site (Origin {origin!r}) may not drive the designer"
)
REFUSED_TOKEN = "forbidden: no valid token; open the address `fuzzyservo designer` printed (it ends in ?token=...)"


def split_authority(value: str) -> tuple[str | None, int | None]:
    """``value`` (``name``, ``name:port``, ``[v6]:port`` or a bare IPv6 address) as its
    lower-case host name (IPv6 in brackets, as a ``Host`` header writes it) and its port;
    ``(None, None)`` when it is none of these."""
    text = value.strip()
    if text.count(":") > 1 and not text.startswith("["):  # a bare IPv6 address
        text = f"[{text}]"
    try:
        parts = urlsplit(f"//{text}")
        name, port = parts.hostname, parts.port
    except ValueError:
        return None, None
    if not name:
        return None, None
    return (f"[{name}]" if ":" in name else name).lower(), port


@dataclass(frozen=True)
class Verdict:
    """What to do with a request: pass it on, refuse it (403 and ``reason``), or set the
    token cookie and redirect to ``location`` (the same address without the token)."""

    action: str  # "pass" | "refuse" | "login"
    reason: str = ""
    location: str = "/"


@dataclass(frozen=True)
class Guard:
    """The checks of one server: its port, the hosts it answers to and its token."""

    port: int
    hosts: frozenset[str]
    token: str

    @classmethod
    def make(cls, port: int, bound: str, allow_hosts: Iterable[str] = ()) -> Guard:
        """A guard with a fresh random token; ``bound`` is the address the server listens on
        (``0.0.0.0`` and ``::`` name no host a browser sends, so they add none)."""
        given = [*allow_hosts, *([] if bound in ("0.0.0.0", "::", "") else [bound])]
        names = {*LOOPBACK, *(split_authority(h)[0] for h in given)} - {None}
        return cls(port, frozenset(names), secrets.token_urlsafe(24))

    def with_port(self, port: int) -> Guard:
        """The same hosts on another port, with a token of its own (the dashboard's)."""
        return Guard(port, self.hosts, secrets.token_urlsafe(24))

    @property
    def cookie(self) -> str:
        """The cookie's name: browsers share cookies between ports, so it names the port."""
        return f"fuzzyservo_token_{self.port}"

    def url(self, host: str, path: str = "/") -> str:
        """The address to print and open: ``http://host:port/path?token=...``."""
        shown = "127.0.0.1" if host in ("0.0.0.0", "", "::") else host
        shown = f"[{shown}]" if ":" in shown and not shown.startswith("[") else shown
        return f"http://{shown}:{self.port}{path}?token={self.token}"

    # ------------------------------------------------------------------ checks
    def allowed_authority(self, authority: str | None) -> bool:
        """``host:port`` names an allowed host on this server's port."""
        if not authority:
            return False
        name, port = split_authority(authority)
        return port == self.port and name in self.hosts

    def allowed_origin(self, origin: str | None) -> bool:
        """No ``Origin`` (not a script's request) or one of ours (``http://host:port``)."""
        if origin is None:
            return True
        try:
            parts = urlsplit(origin.strip())
        except ValueError:
            return False
        return parts.scheme in ("http", "https") and self.allowed_authority(parts.netloc)

    def valid(self, token: str | None) -> bool:
        return bool(token) and hmac.compare_digest(token.encode(), self.token.encode())

    def check(
        self,
        host: str | None,
        origin: str | None,
        path: str,
        query: str,
        cookie_header: str | None,
    ) -> Verdict:
        """The verdict on a request from its ``Host``, ``Origin``, path, query string and
        ``Cookie`` header."""
        if not self.allowed_authority(host):
            return Verdict("refuse", REFUSED_HOST.format(host=(host or "")[:80]))
        if not self.allowed_origin(origin):
            return Verdict("refuse", REFUSED_ORIGIN.format(origin=(origin or "")[:80]))
        if self.valid(_cookie(cookie_header, self.cookie)):
            return Verdict("pass")
        given = parse_qs(query).get("token", [None])[-1]
        if self.valid(given):
            rest = "&".join(
                part for part in query.split("&") if part and not part.startswith("token=")
            )
            return Verdict("login", location=path + (f"?{rest}" if rest else ""))
        return Verdict("refuse", REFUSED_TOKEN)

    def set_cookie(self) -> str:
        """The ``Set-Cookie`` value a login answer carries."""
        return f"{self.cookie}={self.token}; Path=/; HttpOnly; SameSite=Strict"


def _cookie(header: str | None, name: str) -> str | None:
    if not header:
        return None
    jar = SimpleCookie()
    try:
        jar.load(header)
    except CookieError:
        return None
    morsel = jar.get(name)
    return morsel.value if morsel is not None else None


class GuardedWSGI:
    """A WSGI application behind a :class:`Guard` (the optuna-dashboard the designer starts)."""

    def __init__(self, app: Callable, guard: Guard):
        self.app = app
        self.guard = guard

    def __call__(self, environ: dict[str, Any], start_response: Callable) -> Iterable[bytes]:
        verdict = self.guard.check(
            environ.get("HTTP_HOST"),
            environ.get("HTTP_ORIGIN"),
            environ.get("PATH_INFO", "/") or "/",
            environ.get("QUERY_STRING", ""),
            environ.get("HTTP_COOKIE"),
        )
        if verdict.action == "pass":
            return self.app(environ, start_response)
        if verdict.action == "login":
            start_response(
                "302 Found",
                [("Location", verdict.location), ("Set-Cookie", self.guard.set_cookie()),
                 ("Content-Length", "0")],
            )  # fmt: skip
            return [b""]
        body = verdict.reason.encode()
        start_response(
            "403 Forbidden",
            [("Content-Type", "text/plain; charset=utf-8"), ("Content-Length", str(len(body)))],
        )
        return [body]
