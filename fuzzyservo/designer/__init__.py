"""The designer: a local web app to shape a fuzzy controller and watch the loop respond.

Built on Panel and Bokeh (the only place either is imported). :mod:`.session` holds one
browser session's state and does the work with the library's own functions (files →
:func:`~fuzzyservo.io.controllers.controller_from_data`, :func:`~fuzzyservo.simulate`,
:func:`~fuzzyservo.metrics.result_metrics`); :mod:`.files` confines every file the app
opens or writes to the project and output folders; :mod:`.guard` lets only local pages
that know the launch's token drive it, and :mod:`.web` puts it before the server's routes
and optuna-dashboard; :mod:`.app` is the page and serves it (its figures in ``_views``,
its widgets and edits in ``_controls``).
"""

from __future__ import annotations

from pathlib import Path


def serve(
    rig: str | Path,
    controller: str | Path,
    *,
    port: int = 5006,
    host: str = "127.0.0.1",
    out_dir: str | Path = "out/designer",
    show: bool = False,
    ready=None,
    allow_hosts: tuple[str, ...] = (),
    storages: tuple[str, ...] = (),
):
    """Start the designer on ``http://host:port/?token=...`` and block until stopped (Ctrl-C).

    ``rig`` and ``controller`` are files (already resolved by the caller). The page answers
    only requests naming a loopback host, ``host`` or one of ``allow_hosts`` and carrying
    this launch's token (see :mod:`fuzzyservo.designer.guard`); it may open the database
    servers in ``storages`` besides SQLite files in its folders. ``ready`` is called with the
    server and the address with its token once it listens (tests use it).
    """
    from fuzzyservo.errors import require

    require("panel", "designer", "the designer")
    from fuzzyservo.errors import ConfigError
    from fuzzyservo.limits import port_problem

    if port_problem(port):  # refused before anything listens (0: any free port)
        raise ConfigError(f"port: {port_problem(port)}")
    from fuzzyservo.designer.app import run_server

    return run_server(
        Path(rig),
        Path(controller),
        port=port,
        host=host,
        out_dir=Path(out_dir),
        show=show,
        ready=ready,
        allow_hosts=tuple(allow_hosts),
        storages=tuple(storages),
    )
