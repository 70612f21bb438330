"""The designer under attack: foreign pages, forged hosts, paths and URLs from the page.

Replays what a probe of the designer found open: a DNS-rebinding page (``Host:
evil.example``), another site's page opening the websocket (``Origin``), a request with
no token, the optuna-dashboard it starts deleting a study for a foreign page, a page
upload naming an FMU outside the folders, storage URLs of other SQLAlchemy spellings, and
reads outside the documented folders. Every refusal must hold with and without a valid
session, and no file outside the designer's folders may be opened (checked with an audit
hook on every ``open``).
"""

from __future__ import annotations

import http.client
import os
import sys
import time
from pathlib import Path
from urllib.parse import parse_qs, urlsplit

import pytest
from support import DATA, designer_process, free_port

from fuzzyservo.designer.files import Folders
from fuzzyservo.designer.guard import Guard
from fuzzyservo.designer.session import Session
from fuzzyservo.errors import ConfigError, FileError

ROOT = Path(__file__).resolve().parents[2]
RIG = DATA / "rigs" / "dinca_cylinder.yaml"
FLC2 = DATA / "studies" / "controllers" / "flc2_reshaped.yaml"
EVIL = "evil.example"


# --------------------------------------------------------------------------- the guard itself
@pytest.fixture
def guard() -> Guard:
    return Guard.make(5006, "127.0.0.1", allow_hosts=("rig-pc.lab",))


def _cookie(g: Guard, token: str | None = None) -> str:
    return f"{g.cookie}={token or g.token}"


@pytest.mark.parametrize(
    ("host", "origin"),
    [
        (f"{EVIL}:5006", None),  # DNS rebinding: the page's own name
        (f"{EVIL}:5006", f"http://{EVIL}:5006"),  # Origin equals Host: still foreign
        ("127.0.0.1:5006", f"http://{EVIL}:5006"),  # a foreign page naming the right host
        ("127.0.0.1:5006", f"http://{EVIL}"),
        ("127.0.0.1:5006", "null"),  # a sandboxed frame or a file:// page
        ("127.0.0.1:5006", "http://127.0.0.1:5007"),  # another local port is another origin
        ("127.0.0.1:5007", None),  # the port is part of the host
        ("127.0.0.1", None),
        (None, None),
        ("", None),
        ("127.0.0.1:5006@evil.example", None),
        ("localhost.evil.example:5006", None),
        ("127.0.0.1:99999", None),
    ],
)
def test_forged_host_or_origin_is_refused_with_and_without_a_session(guard, host, origin):
    for cookie in (None, _cookie(guard)):
        for query in ("", f"token={guard.token}"):
            verdict = guard.check(host, origin, "/", query, cookie)
            assert verdict.action == "refuse", (host, origin, cookie, query)
            assert verdict.reason.startswith("forbidden")


@pytest.mark.parametrize(
    "host", ["127.0.0.1:5006", "localhost:5006", "LOCALHOST:5006", "[::1]:5006", "rig-pc.lab:5006"]
)
def test_local_hosts_with_the_token_pass(guard, host):
    origin = f"http://{host}"
    assert guard.check(host, origin, "/ws", "", _cookie(guard)).action == "pass"
    assert guard.check(host, None, "/", "", _cookie(guard)).action == "pass"
    login = guard.check(host, None, "/", f"a=1&token={guard.token}", None)
    assert (login.action, login.location) == ("login", "/?a=1")
    # no token, a wrong one, another port's cookie: refused
    assert guard.check(host, None, "/", "", None).action == "refuse"
    assert guard.check(host, None, "/", "token=guess", _cookie(guard, "guess")).action == "refuse"
    other = guard.with_port(5007)
    assert guard.check(host, None, "/", "", _cookie(other)).action == "refuse"
    assert "HttpOnly" in guard.set_cookie() and "SameSite=Strict" in guard.set_cookie()


def test_allowed_names_are_read_like_the_host_header():
    """An ``--allow-host`` or bound address given with a port, in capitals or as a bare
    IPv6 address is the name a ``Host`` header carries."""
    g = Guard.make(5006, "FD00::7", allow_hosts=("Rig-PC.lab:80", "fe80::1", " "))
    assert {"rig-pc.lab", "[fe80::1]", "[fd00::7]"} <= g.hosts
    for host in ("rig-pc.lab:5006", "[fe80::1]:5006", "[FD00::7]:5006"):
        assert g.allowed_authority(host), host
    assert not g.allowed_authority("fe80::1:5006")  # a bare v6 with a port is no Host header


def test_every_launch_has_its_own_token():
    tokens = {Guard.make(5006, "127.0.0.1").token for _ in range(20)}
    assert len(tokens) == 20 and all(len(t) >= 32 for t in tokens)


# --------------------------------------------------------------------------- the live server


@pytest.fixture(scope="module")
def designer(tmp_path_factory):
    """``fuzzyservo designer`` as the user starts it; yields (port, token)."""
    work = tmp_path_factory.mktemp("designer_security")
    with designer_process(work, work / "out") as url:
        port = urlsplit(url).port
        yield port, parse_qs(urlsplit(url).query)["token"][0]


def _request(port: int, path: str, headers: dict[str, str], method: str = "GET"):
    conn = http.client.HTTPConnection("127.0.0.1", port, timeout=60)
    conn.putrequest(method, path, skip_host=True, skip_accept_encoding=True)
    for name, value in headers.items():
        conn.putheader(name, value)
    conn.endheaders()
    reply = conn.getresponse()
    body = reply.read().decode(errors="replace")
    conn.close()
    return reply.status, body, reply


WEBSOCKET = {
    "Upgrade": "websocket",
    "Connection": "Upgrade",
    "Sec-WebSocket-Key": "dGhlIHNhbXBsZSBub25jZQ==",
    "Sec-WebSocket-Version": "13",
}


def test_the_designer_refuses_forged_hosts_and_origins_and_keeps_serving(designer):
    port, token = designer
    cookie = {"Cookie": f"fuzzyservo_token_{port}={token}"}
    local = f"127.0.0.1:{port}"
    forged = [
        ("/", {"Host": f"{EVIL}:{port}"}),
        (f"/?token={token}", {"Host": f"{EVIL}:{port}"}),
        ("/", {"Host": f"{EVIL}:{port}", **cookie}),
        ("/ws", {"Host": f"{EVIL}:{port}", "Origin": f"http://{EVIL}:{port}", **WEBSOCKET}),
        ("/ws", {"Host": f"{EVIL}:{port}", "Origin": f"http://{EVIL}:{port}", **WEBSOCKET,
                 **cookie}),
        ("/ws", {"Host": local, "Origin": f"http://{EVIL}:{port}", **WEBSOCKET, **cookie}),
        ("/", {"Host": local}),  # no token
        ("/ws", {"Host": local, "Origin": f"http://{local}", **WEBSOCKET}),  # no token
        ("/static/js/bokeh.min.js", {"Host": f"{EVIL}:{port}"}),
    ]  # fmt: skip
    for path, headers in forged:
        status, body, _ = _request(port, path, headers)
        assert status == 403 and body.startswith("forbidden"), (path, headers, status)
    # the user's own browser: the printed address sets the cookie, then the page loads
    status, _, reply = _request(port, f"/?token={token}", {"Host": local})
    assert status == 302 and reply.getheader("Location") == "/"
    assert f"fuzzyservo_token_{port}={token}" in reply.getheader("Set-Cookie")
    status, body, _ = _request(port, "/", {"Host": local, **cookie})
    assert status == 200 and "bokeh" in body.lower()
    status, _, _ = _request(port, "/ws", {"Host": local, "Origin": f"http://{local}",
                                          **WEBSOCKET, **cookie})  # fmt: skip
    assert status != 403


# --------------------------------------------------------------------------- the dashboard
def test_the_dashboard_refuses_foreign_pages_and_keeps_the_study(tmp_path):
    pytest.importorskip("optuna_dashboard", reason="pip install optuna-dashboard")
    import optuna

    from fuzzyservo.designer.web import start_dashboard

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    url = f"sqlite:///{tmp_path / 'study.db'}"
    study = optuna.create_study(study_name="kept", storage=url)
    study.optimize(lambda t: t.suggest_float("x", 0, 1), n_trials=3)
    link = start_dashboard(url, Guard.make(free_port(), "127.0.0.1"))
    port = urlsplit(link).port  # the next free one when this process runs another dashboard
    token = parse_qs(urlsplit(link).query)["token"][0]
    cookie = {"Cookie": f"fuzzyservo_token_{port}={token}"}
    local = f"127.0.0.1:{port}"
    deadline = time.monotonic() + 30
    while True:
        try:
            status, _, _ = _request(port, "/api/studies", {"Host": local, **cookie})
            break
        except OSError:
            if time.monotonic() > deadline:
                raise
            time.sleep(0.2)
    assert status == 200
    attacks = [
        {"Host": f"{EVIL}:{port}"},
        {"Host": f"{EVIL}:{port}", **cookie},
        {"Host": f"{EVIL}:{port}", "Origin": f"http://{EVIL}:{port}", **cookie},
        {"Host": local, "Origin": f"http://{EVIL}:{port}", **cookie},
        {"Host": local},  # no token
    ]
    for headers in attacks:
        status, body, _ = _request(port, "/api/studies/1", headers, method="DELETE")
        assert status == 403 and body.startswith("forbidden"), headers
    assert len(optuna.load_study(study_name="kept", storage=url).trials) == 3
    status, body, _ = _request(port, "/api/studies", {"Host": local, **cookie})
    assert status == 200 and "kept" in body


# --------------------------------------------------------------------------- files and URLs
_OPENED: list[str] = []


def _audit(event: str, args: tuple) -> None:
    if event == "open" and _OPENED and isinstance(args[0], str | bytes | os.PathLike):
        _OPENED.append(os.fsdecode(args[0]))


sys.addaudithook(_audit)  # records only while a test has put a marker in _OPENED


class _Watch:
    """Paths opened (by Python's ``open``, sqlite, zipfile ...) inside the ``with`` block."""

    def __enter__(self) -> list[str]:
        _OPENED.clear()
        _OPENED.append("<start>")
        return _OPENED

    def __exit__(self, *exc) -> None:
        self.seen = _OPENED[1:]
        _OPENED.clear()


@pytest.fixture
def outside(tmp_path) -> Path:
    """A folder outside the designer's, holding an FMU, a controller file and a database."""
    folder = tmp_path / "outside"
    folder.mkdir()
    (folder / "plant.fmu").write_bytes(b"PK\x05\x06" + bytes(18))  # an empty zip
    (folder / "secret.yaml").write_text("kind: fuzzy\nname: secret\n")
    (folder / "study.db").write_bytes(b"")
    return folder


@pytest.fixture
def session(tmp_path) -> Session:
    work = tmp_path / "work"
    (work / "out").mkdir(parents=True)
    (work / "notes.yaml").write_text("kind: fuzzy\n")
    return Session.open(Folders.make(DATA, work / "out" / "designer", work), RIG, FLC2)


def _never_opened(seen: list[str], folder: Path) -> None:
    touched = [p for p in seen if Path(p).resolve().is_relative_to(folder.resolve())]
    assert not touched, touched


def test_an_upload_naming_an_outside_fmu_is_refused_before_anything_opens_it(session, outside):
    for text in (
        f"kind: fmu\nfile: {outside / 'plant.fmu'}\n",
        f"kind: fmu\nfile: {outside / 'plant.fmu'}\nname: x\nsample_time: 0.01\n",
        "kind: fmu\nfile: ../../outside/plant.fmu\n",
        "kind: P\ngain: 3\n",
    ):
        watch = _Watch()
        with watch, pytest.raises(ConfigError, match="the designer edits 'kind: fuzzy'"):
            session.open_upload("evil.yaml", text.encode())
        _never_opened(watch.seen, outside)
    # a controller file of another kind inside the folders is refused the same way
    fmu_file = session.folders.output / "fmu.yaml"
    fmu_file.parent.mkdir(parents=True, exist_ok=True)
    fmu_file.write_text(f"kind: fmu\nfile: {outside / 'plant.fmu'}\n")
    watch = _Watch()
    with watch, pytest.raises(ConfigError, match="edits 'kind: fuzzy'"):
        session.open_file(str(fmu_file))
    _never_opened(watch.seen, outside)


def test_paths_from_the_page_outside_the_documented_folders_are_refused(session, outside):
    work = session.folders.work
    names = [
        str(outside / "secret.yaml"),
        "../outside/secret.yaml",
        f"{work}/notes.yaml",  # the working folder itself is not read, only rigs/ studies/ out/
        "notes.yaml",
        str(ROOT / "pyproject.toml"),
        str(ROOT / ".venv" / "pyvenv.cfg"),
        "/etc/passwd",
        "~/.ssh/id_rsa",
        "x" * 5000 + ".yaml",
    ]
    for name in names:
        watch = _Watch()
        with watch, pytest.raises(ConfigError) as caught:
            session.open_file(name)
        _never_opened(watch.seen, outside)
        assert len(str(caught.value)) < 600, name  # a long name is cut, not echoed whole
    for name in (str(outside / "x.yaml"), "../x.yaml", "/tmp/x.fis"):
        with pytest.raises(ConfigError, match="outside"):
            session.save_yaml(name) if name.endswith(".yaml") else session.save_fis(name)
    assert not (outside / "x.yaml").exists()


@pytest.mark.parametrize(
    "url",
    [
        "sqlite:///{o}/study.db",
        "sqlite+pysqlite:///{o}/study.db",
        "sqlite+pysqlite:///{o}/new.db",
        "sqlite:///file:{o}/new.db?mode=rwc&uri=true",
        "sqlite:///{w}/out/../../outside/study.db",
        "sqlite://",
        "sqlite:///:memory:",
        "postgresql://user:pw@127.0.0.1:1/db",
        "postgresql+psycopg2://user@10.255.255.1:5432/db",
        "mysql://root@127.0.0.1:3306/x",
        "not a url",
        "sqlite:///" + "a" * 5000,
    ],
)
def test_storage_urls_of_any_dialect_outside_the_folders_are_refused(session, outside, url):
    given = url.format(o=outside, w=session.folders.work)
    watch = _Watch()
    with watch, pytest.raises(ConfigError) as caught:
        session.open_study("dinca_flc", given)
    _never_opened(watch.seen, outside)
    assert not (outside / "new.db").exists()
    assert len(str(caught.value)) < 600


def test_a_database_server_named_on_the_command_line_may_be_opened(tmp_path):
    url = "postgresql://user@127.0.0.1:1/db"
    folders = Folders.make(DATA, tmp_path / "out", tmp_path, storages=(url,))
    assert folders.storage_url(url) == (url, None)
    with pytest.raises(ConfigError, match="--storage"):
        folders.storage_url("postgresql://user@127.0.0.1:2/db")


@pytest.mark.parametrize(
    "name", ["x" * 5000 + ".yaml", "a/" * 3000 + "b.yaml", "x" * 300 + ".yaml", "a/../" * 300]
)
def test_a_name_too_long_to_save_is_one_line_and_writes_nothing(session, name):
    before = session.data
    with pytest.raises(ConfigError) as caught:
        session.save_yaml(name)
    assert len(str(caught.value)) < 600
    assert session.data is before
    output = session.folders.output
    assert not output.exists() or not any(output.iterdir())


def test_a_failed_write_is_one_line_and_leaves_the_session(session):
    """A folder where the file goes (the same failure as a full disk or no permission)."""
    (session.folders.output / "taken.yaml").mkdir(parents=True)
    with pytest.raises(FileError, match="cannot write"):
        session.save_yaml("taken.yaml")
    assert session.save_yaml("free.yaml").is_file()


def test_an_alias_bomb_or_deep_upload_is_one_line_and_the_session_goes_on(session):
    """What killed the designer process (a 445-byte upload) is now a refused edit: the
    page shows the line and keeps the last good controller."""
    levels = ['a0: &a0 ["x", "x", "x", "x", "x", "x", "x", "x", "x", "x"]']
    levels += [f"a{k}: &a{k} [{', '.join([f'*a{k - 1}'] * 10)}]" for k in range(1, 9)]
    bomb = "kind: fuzzy\n" + "\n".join(levels) + "\n"
    deep = "kind: fuzzy\nx: " + "[" * 20_000 + "]" * 20_000 + "\n"
    before = session.controller
    for text in (bomb, deep):
        with pytest.raises(ConfigError) as caught:
            session.open_upload("bomb.yaml", text.encode())
        assert len(str(caught.value)) < 400
        assert session.controller is before
    assert session.run().result.status == "ok"
