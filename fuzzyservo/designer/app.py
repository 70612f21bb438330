"""The designer page: Panel widgets and Bokeh figures around a :class:`~.session.Session`,
and the server that serves it.

Every change calls the session (which builds, checks and simulates with the library)
and then redraws inside one ``hold`` so the browser gets one patch per change. Only
the edited controller is simulated again; the baselines are run once per rig and
scenario.

The page's figures are drawn by :class:`~._views.Views` and its widgets and edits are
:class:`~._controls.Controls`; :class:`Designer` puts them together and runs the update
cycle. :func:`run_server` serves one :class:`Designer` per browser session behind the
guard (:mod:`.web`).
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

import panel as pn

from fuzzyservo.atomic import shown_path
from fuzzyservo.designer._controls import Controls
from fuzzyservo.designer._style import CSS, DENSE_TABLE, METRICS_WIDTH, SIDEBAR, TAB_WIDTH, _esc
from fuzzyservo.designer._views import Views
from fuzzyservo.designer.files import Folders
from fuzzyservo.designer.guard import LOOPBACK, Guard
from fuzzyservo.designer.session import Session, StudyView
from fuzzyservo.designer.web import install_guard
from fuzzyservo.errors import FuzzyservoError

_PROFILE = bool(os.environ.get("FUZZYSERVO_DESIGNER_PROFILE"))


class Designer(Views, Controls):
    """The page of one browser session."""

    def __init__(self, session: Session, guard: Guard):
        self.s = session
        self.web_guard = guard
        self.updates = 0
        self.study: StudyView | None = None
        self.status = pn.pane.HTML("", css_classes=["fs-status"], sizing_mode="stretch_width")
        self.title = pn.pane.HTML("", sizing_mode="stretch_width")
        self.metrics = pn.pane.HTML("", css_classes=["fs-metrics"], width=METRICS_WIDTH)
        self._build_response()
        self._build_curve()
        self._build_firing()
        self.design_box = pn.Column(sizing_mode="stretch_width")
        self.mf_box = pn.Column()
        self.rules_box = pn.Column()
        self.yaml_view = pn.widgets.TextAreaInput(
            value="", height=400, width=TAB_WIDTH, disabled=True
        )
        self.sidebar = pn.Column(
            self._rig_widgets(),
            pn.pane.Markdown("### Seven-term design and gains"),
            self.design_box,
            self._file_widgets(),
            self._study_widgets(),
            width=SIDEBAR,
        )
        self.rebuild()

    # ================================================================ layout
    def view(self) -> pn.viewable.Viewable:
        tabs = pn.Tabs(
            ("Membership functions", self.mf_box),
            ("Control curve", self.curve_fig_pane),
            ("Rules and firing", pn.Column(self.rules_box, self.firing_box)),
            ("Controller file", self.yaml_view),
            dynamic=True,
        )
        main = pn.Column(
            self.title,
            self.status,
            pn.Row(self.response_pane, pn.Column("### Metrics", self.metrics)),
            tabs,
        )
        return pn.Row(self.sidebar, main)

    # ================================================================ updates
    def rebuild(self) -> None:
        """Rebuild everything that depends on the controller's structure (variables, rules)."""
        self.mf_figs = {role: self._mf_figure(role) for role in self.s.roles()}
        self._drawn_vars: dict[str, object] = {}
        import pandas as pd

        self.bp_tables = {}
        boxes = []
        for role, (fig, *_rest) in self.mf_figs.items():
            table = pn.widgets.Tabulator(pd.DataFrame(), show_index=False, sortable=False,
                                         selectable=False, width=METRICS_WIDTH, layout="fit_columns",
                                         widths={"term": 42, "shape": 56}, stylesheets=[DENSE_TABLE])  # fmt: skip
            table.on_edit(
                lambda ev, role=role, table=table: self._guard(self._on_breakpoint, role, table, ev)
            )
            self.bp_tables[role] = table
            boxes.append(
                pn.Row(
                    pn.pane.Bokeh(fig), pn.Column(f"**{role} breakpoints** (edit a cell)", table)
                )
            )
        self.mf_box.objects = boxes
        self.pick_de.visible = len(self.s.controller.system.inputs) == 2
        self.refresh(structure=True, rebuilt=True)

    def refresh(self, structure: bool = False, rebuilt: bool = False, rules: bool = False) -> None:
        """Redraw after a change: the fuzzy views, the loop and the metrics, in one patch.

        ``structure``: variables or their kind changed (sliders and tables are rebuilt);
        ``rules``: the rule base changed (the rule table is rebuilt). A slider move needs
        neither, so it only sends new data for the figures that exist.
        """
        if structure and not rebuilt and [*self.mf_figs] != self.s.roles():
            self.rebuild()
            return
        t0 = time.perf_counter()
        t_epoch = time.time()
        self.updates += 1
        with pn.io.hold():
            if structure:
                self._draw_design()
            self._draw_mf()
            if structure or rules:
                self._draw_rules()
            self._draw_firing()
            self._draw_curve()
            self._draw_runs()
            self.yaml_view.value = self.s.yaml_text()
            s = self.s
            self.title.object = (
                f"<h2 style='margin:4px 0'>fuzzyservo designer — {_esc(s.controller.name)} on "
                f"{_esc(s.rig.name)} · {_esc(s.scenario)}</h2>"
            )
            self._say(f"update {self.updates}: {self.sim_note}; redrawn in "
                      f"{(time.perf_counter() - t0) * 1e3:.0f} ms")  # fmt: skip
        if _PROFILE:
            print(
                f"refresh {self.updates} at {time.time():.3f} (started {t_epoch:.3f}): {(time.perf_counter() - t0) * 1e3:.0f} ms with the patch",
                file=sys.stderr,
                flush=True,
            )

    def _guard(self, fn, *args) -> None:
        """Run a change; a bad value shows one red line and leaves the last good state.

        Everything runs inside one ``hold``: Bokeh models may only change under the
        document's lock, and the browser gets one patch.
        """
        with pn.io.hold():
            try:
                fn(*args)
            except (FuzzyservoError, ValueError) as exc:
                self._say(str(exc), error=True)
                self.rebuild_soft()
            except OSError as exc:  # a full disk, a name too long, a folder where a file goes
                where = f"{shown_path(exc.filename)}: " if exc.filename else ""
                self._say(f"{where}{exc.strerror or exc}; nothing was changed", error=True)
                self.rebuild_soft()

    def rebuild_soft(self) -> None:
        """Put the tables and dragged points back to the last good controller after a refused edit."""
        if [*getattr(self, "mf_figs", {})] == self.s.roles():
            self._drawn_vars = {}
            self._draw_mf()

    def _say(self, text: str, error: bool = False) -> None:
        cls = "fs-error" if error else "fs-ok"
        self.status.object = f"<div class='{cls}' id='fs-status'>{_esc(_cut(text, 400))}</div>"


def _cut(text: str, limit: int) -> str:
    return text if len(text) <= limit else f"{text[: limit - 1]}…"


def run_server(
    rig: Path,
    controller: Path,
    *,
    port: int,
    host: str,
    out_dir: Path,
    show: bool,
    ready=None,
    allow_hosts: tuple[str, ...] = (),
    storages: tuple[str, ...] = (),
):
    """Check the files once (a bad file fails here, before the server starts), then serve."""
    from fuzzyservo.io.paths import data_root

    folders = Folders.make(data_root(), out_dir, Path.cwd(), storages=storages)
    Session.open(folders, rig, controller)  # raises ConfigError for a bad file
    state: dict[str, Guard] = {}

    def page():
        session = Session.open(folders, rig, controller)
        return Designer(session, guard=state["guard"]).view()

    pn.extension("tabulator", raw_css=[CSS], notifications=False)
    try:
        server = pn.serve(
            {"/": page},
            port=port,
            address=host,
            # Bokeh's own origin list, kept as a second check (it takes no [v6] names)
            websocket_origin=[
                f"{h}:{port}" for h in (*LOOPBACK, host, *allow_hosts) if "[" not in h
            ],
            show=False,
            start=False,
            title="fuzzyservo designer",
            verbose=False,
        )
    except OSError as exc:
        raise FuzzyservoError(
            f"cannot listen on {host}:{port} ({exc.strerror or exc}); give another --port"
        ) from None
    guard = state["guard"] = Guard.make(server.port, host, allow_hosts)
    install_guard(server, guard)
    url = guard.url(host)
    print(f"fuzzyservo designer on {url} (Ctrl-C stops it)", flush=True)
    if host not in LOOPBACK:
        print(
            f"listening on {host}: any machine that reaches it and knows the address above "
            "can drive the designer",
            flush=True,
        )
    server.start()
    if show:
        import webbrowser

        webbrowser.open(url)
    if ready is not None:
        ready(server, url)
    try:
        server.io_loop.start()
    except KeyboardInterrupt:
        print("designer stopped", file=sys.stderr)
    return server
