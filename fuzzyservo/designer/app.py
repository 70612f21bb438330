"""The designer page: Panel widgets and Bokeh figures around a :class:`~.session.Session`.

Every change calls the session (which builds, checks and simulates with the library)
and then redraws inside one ``hold`` so the browser gets one patch per change. Only
the edited controller is simulated again; the baselines are run once per rig and
scenario.
"""

from __future__ import annotations

import os
import sys
import threading
import time
from pathlib import Path

import numpy as np
import panel as pn
from bokeh.models import (
    ColorBar,
    ColumnDataSource,
    FactorRange,
    HoverTool,
    LinearColorMapper,
    PointDrawTool,
    Range1d,
    Span,
)
from bokeh.plotting import figure
from matplotlib.colors import to_hex
from tornado.web import RequestHandler

from fuzzyservo.atomic import shown_path
from fuzzyservo.designer.files import Folders
from fuzzyservo.designer.guard import LOOPBACK, Guard, GuardedWSGI, Verdict
from fuzzyservo.designer.session import Session, StudyView, metrics_rows
from fuzzyservo.display import (
    PRESSURE_COLOURS,
    axis_label,
    controller_colour,
    metric_units,
    saturated_spans,
    to_display,
)
from fuzzyservo.errors import FuzzyservoError
from fuzzyservo.metrics import METRIC_DOCS
from fuzzyservo.tuning import MAIN_STUDY

TERM_COLOURS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2",
                "#7f7f7f", "#bcbd22", "#17becf")  # fmt: skip
REFERENCE_COLOUR = to_hex("tab:green")
MAX_COMPARED = 5
_PROFILE = bool(os.environ.get("FUZZYSERVO_DESIGNER_PROFILE"))
# sized for a 1,280 x 800 window (a laptop): sidebar, loop figures and metrics side by side,
# the tabs below as wide as the figures and metrics together; nothing scrolls sideways
SIDEBAR = 300
WIDTH = 560
METRICS_WIDTH = 370
TAB_WIDTH = WIDTH + METRICS_WIDTH + 10
CSS = """
.fs-metrics {overflow-x: auto;}
.fs-metrics table {border-collapse: collapse; font: 12px monospace;}
.fs-metrics td, .fs-metrics th {border-bottom: 1px solid #ddd; padding: 2px 5px; text-align: right;}
.fs-metrics td:first-child, .fs-metrics th:first-child {text-align: left;}
.fs-error {color: #b00020;}
"""
# a table's cells in the sidebar or beside a figure: small enough for six numbers in 370 px
DENSE_TABLE = (
    ".tabulator-cell, .tabulator-col-title {font-size: 12px;} .tabulator-cell {padding: 4px 3px;}"
)


def _colour(k: int) -> str:
    return to_hex(controller_colour(k))


class Designer:
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

    # ================================================================ response
    def _build_response(self) -> None:
        kw = {"width": WIDTH, "height": 210, "tools": "pan,xwheel_zoom,box_zoom,reset,save"}
        self.fig_y = figure(title="(a) reference and position", **kw)
        self.fig_i = figure(title="(b) valve current with limits", x_range=self.fig_y.x_range, **kw)
        self.fig_p = figure(title="(c) pressures", x_range=self.fig_y.x_range, **kw)
        self.fig_p.xaxis.axis_label = "time [s]"
        self.src_ref = ColumnDataSource({"t": [], "r": []})
        self.fig_y.line("t", "r", source=self.src_ref, color=REFERENCE_COLOUR, line_dash="dashed",
                        legend_label="reference", line_width=1.5)  # fmt: skip
        self.src_runs: list[ColumnDataSource] = []
        self.run_renderers = []
        n_fixed = 1 + len(self.s.baselines)
        # the edited controller (k = 0) is added last so that it is drawn on top
        for k in reversed(range(n_fixed + MAX_COMPARED)):
            src = ColumnDataSource({"t": [], "y": [], "i": []})
            colour = _colour(k)
            dash = "solid" if k < n_fixed else "dotdash"
            width = 2.0 if k == 0 else 1.3
            ry = self.fig_y.line(
                "t", "y", source=src, color=colour, line_width=width, line_dash=dash
            )
            ri = self.fig_i.line(
                "t", "i", source=src, color=colour, line_width=width, line_dash=dash
            )
            self.src_runs.insert(0, src)
            self.run_renderers.insert(0, (ry, ri))
        self.limit_spans = [
            Span(
                location=0, dimension="width", line_color="#444", line_dash="dotted", line_width=1.2
            )
            for _ in range(2)
        ]
        for span in self.limit_spans:
            self.fig_i.add_layout(span)
        # the edited controller's saturated intervals, shaded as in `compare`'s figure
        self.src_sat = ColumnDataSource({"x0": [], "x1": []})
        self.fig_i.vstrip(x0="x0", x1="x1", source=self.src_sat, fill_color=_colour(0),
                          fill_alpha=0.12, line_width=0, legend_label="saturated (edited)")  # fmt: skip
        self.src_p = ColumnDataSource({"t": []})
        self._drawn_key: tuple | None = None
        self._labels: dict[int, str] = {}
        self.pressure_renderers: dict[str, object] = {}
        self.response_pane = pn.pane.Bokeh(_column(self.fig_y, self.fig_i, self.fig_p))

    def _draw_runs(self) -> None:
        """Simulate the edited controller and redraw it; the others only when they change."""
        s = self.s
        edited = s.run(name=f"{s.controller.name} (edited)")
        others = [*s.baseline_runs(), *s.compared_runs()[:MAX_COMPARED]]
        runs = [edited, *others]
        first = edited.result
        out_name = first.output_name
        key = (str(s.rig_path), s.scenario, tuple(r.name for r in others))
        fixed = key == self._drawn_key
        for k, (src, (ry, ri)) in enumerate(zip(self.src_runs, self.run_renderers, strict=True)):
            if fixed and k > 0:
                break
            if k < len(runs):
                r = runs[k].result
                y, _ = to_display(r, out_name, r.output)
                i, _ = to_display(r, r.actuator_name, r.actuator)
                src.data = {"t": r.t, "y": y, "i": i}
                ry.visible = ri.visible = True
                label = runs[k].name if r.status == "ok" else f"{runs[k].name} ({r.status})"
                if label != self._labels.get(k):
                    _set_legend(self.fig_y, ry, label)
                    self._labels[k] = label
            else:
                ry.visible = ri.visible = False
        spans = saturated_spans(first)
        self.src_sat.data = {"x0": [a for a, _ in spans], "x1": [e for _, e in spans]}
        pressures = [n for n in first.signals if first.units.get(n) == "Pa"]
        data = {"t": first.t}
        p_unit = ""
        for name in pressures:
            data[name], p_unit = to_display(first, name, first.signals[name])
        self.src_p.data = data
        if not fixed:
            self._draw_fixed(first, pressures, p_unit)
            self._drawn_key = key
        self._draw_metrics(runs)
        status = f" · status {first.status}: {first.message}" if first.status != "ok" else ""
        self.sim_note = (
            f"simulated {first.t[-1] + first.sample_time_s:.3g} s in "
            f"{edited.seconds * 1e3:.0f} ms{status}"
        )

    def _draw_fixed(self, first, pressures: list[str], p_unit: str) -> None:
        """What changes with the rig and scenario only: reference, limits, axes, pressure lines."""
        out_name = first.output_name
        ref, unit = to_display(first, out_name, first.reference_output)
        self.src_ref.data = {"t": first.t, "r": ref}
        self.fig_y.yaxis.axis_label = axis_label(out_name, unit)
        limits, i_unit = to_display(first, first.actuator_name, np.asarray(first.actuator_limits))
        self.fig_i.yaxis.axis_label = axis_label(first.actuator_name, i_unit)
        self.fig_y.title.text = f"(a) reference and {axis_label(out_name, '')}"
        self.fig_i.title.text = f"(b) {axis_label(first.actuator_name, '')} with its limits"
        for span, limit in zip(self.limit_spans, limits, strict=True):
            span.location = float(limit) if np.isfinite(limit) else None
        for k, name in enumerate(pressures):
            if name not in self.pressure_renderers:
                colour = to_hex(PRESSURE_COLOURS.get(name, TERM_COLOURS[k % len(TERM_COLOURS)]))
                self.pressure_renderers[name] = self.fig_p.line(
                    "t", name, source=self.src_p, color=colour, legend_label=name, line_width=1.2
                )
        for name, renderer in self.pressure_renderers.items():
            renderer.visible = name in pressures
        self.fig_p.yaxis.axis_label = f"pressure [{p_unit}]" if p_unit else "pressure"
        for fig in (self.fig_y, self.fig_i, self.fig_p):
            fig.legend.location = "top_right"
            fig.legend.label_text_font_size = "8pt"
            fig.legend.click_policy = "hide"

    def _draw_metrics(self, runs) -> None:
        units = metric_units(runs[0].result)
        head = "".join(f"<th>{_esc(r.name)}</th>" for r in runs)
        rows = "".join(
            f"<tr title='{_esc(METRIC_DOCS[row[0]])}'><td>{_esc(units.label(row[0]))}</td>"
            + "".join(f"<td>{v}</td>" for v in row[1:])
            + "</tr>"
            for row in metrics_rows(runs)
        )
        self.metrics.object = (
            f"<table id='fs-metrics' data-update='{self.updates}'><tr><th>metric</th>{head}</tr>"
            f"{rows}</table><p style='font-size:11px;color:#666'>worst step after the warm-up; "
            "integrals and saturation summed (hover a row for its definition)</p>"
        )

    # ================================================================ fuzzy views
    def _mf_figure(self, role: str):
        var = self.s.variable(role)
        fig = figure(title=f"{role} {var.name}: membership functions", width=WIDTH, height=230,
                     tools="pan,wheel_zoom,reset", y_range=Range1d(-0.05, 1.1))  # fmt: skip
        lines = ColumnDataSource({"xs": [], "ys": [], "colour": [], "term": []})
        fig.multi_line("xs", "ys", source=lines, color="colour", line_width=2)
        points = ColumnDataSource({"x": [], "y": [], "term": [], "k": [], "colour": []})
        dots = fig.scatter("x", "y", source=points, size=9, color="colour", alpha=0.7)
        labels = ColumnDataSource({"x": [], "y": [], "term": [], "align": []})
        fig.text("x", "y", text="term", source=labels, text_align="align",
                 text_font_size="9pt", y_offset=-2)  # fmt: skip
        draw = PointDrawTool(renderers=[dots], add=False)
        fig.add_tools(draw, HoverTool(renderers=[dots], tooltips=[("term", "@term"), ("x", "@x")]))
        fig.toolbar.active_tap = draw
        picked = Span(location=0, dimension="height", line_color="#b00020", line_dash="dashed")
        if role != "output":
            fig.add_layout(picked)
        fig.xaxis.axis_label = var.name
        points.on_change("data", lambda attr, old, new, role=role: self._on_drag(role, old, new))
        return fig, lines, points, labels, picked

    def _draw_mf(self) -> None:
        for role, (fig, lines, points, labels, _) in self.mf_figs.items():
            var = self.s.variable(role)
            if self._drawn_vars.get(role) == var:
                continue
            self._drawn_vars[role] = var
            u, table = var.table()
            colours = [TERM_COLOURS[k % len(TERM_COLOURS)] for k in range(len(var.terms))]
            lines.data = {"xs": [u] * len(var.terms), "ys": list(table), "colour": colours,
                          "term": [t.name for t in var.terms]}  # fmt: skip
            px, py, pt, pk, pc = [], [], [], [], []
            for k, term in enumerate(var.terms):
                for j, x in enumerate(term.breakpoints):
                    if var.low - 1e-12 <= x <= var.high + 1e-12:
                        px.append(x)
                        py.append(float(np.interp(x, u, table[k])))
                        pt.append(term.name)
                        pk.append(j)
                        pc.append(colours[k])
            self._setting_points = True
            points.data = {"x": px, "y": py, "term": pt, "k": pk, "colour": pc}
            self._setting_points = False
            peaks = [float(u[np.argmax(row)]) for row in table]
            labels.data = {
                "x": peaks,
                "y": [1.02] * len(peaks),
                "term": [t.name for t in var.terms],
                "align": [_label_align(x, var.low, var.high) for x in peaks],
            }
            fig.x_range.start, fig.x_range.end = var.low, var.high
            fig.title.text = (
                f"{role} {var.name} [{var.low:.4g}, {var.high:.4g}]: membership functions"
                + (" (seven-term design)" if self.s.design(role) else " (explicit terms)")
            )
            self.bp_tables[role].value = _breakpoint_frame(var)

    def _build_curve(self) -> None:
        self.curve_fig_pane = pn.Column()
        self.src_curve = ColumnDataSource({"e": [], "u": []})
        self.src_pick = ColumnDataSource({"x": [], "y": []})
        self.src_surface = ColumnDataSource({"image": [], "x": [], "y": [], "dw": [], "dh": []})
        self.curve_inputs = 0

    def _curve_figure(self, n_inputs: int):
        """The control curve (one input) or surface (two), built once per structure."""
        tools = "pan,wheel_zoom,box_zoom,reset,save"
        if n_inputs == 1:
            fig = figure(title="control curve u = G_u·F(G_e·e) (before limits)", width=TAB_WIDTH,
                         height=330, tools=tools)  # fmt: skip
            for k, (name, c) in enumerate(self.s.baselines.items(), start=1):
                if hasattr(c, "curve") and len(c.system.inputs) == 1:
                    fig.line("e", name, source=self.src_curve, line_width=1.3, color=_colour(k),
                             line_dash="dashed", legend_label=name)  # fmt: skip
            fig.line("e", "u", source=self.src_curve, line_width=2, color=_colour(0),
                     legend_label="edited")  # fmt: skip
            fig.legend.location = "top_left"
            fig.xaxis.axis_label, fig.yaxis.axis_label = "error e [V]", "command u [V]"
        else:
            fig = figure(title="control surface u(e, ė) (before limits)", width=TAB_WIDTH, height=420,
                         tools=tools)  # fmt: skip
            self.surface_mapper = LinearColorMapper(palette="Viridis256")
            fig.image("image", x="x", y="y", dw="dw", dh="dh", source=self.src_surface,
                      color_mapper=self.surface_mapper)  # fmt: skip
            fig.add_layout(ColorBar(color_mapper=self.surface_mapper, title="u [V]"), "right")
            fig.xaxis.axis_label, fig.yaxis.axis_label = "error e [V]", "error rate ė [V/s]"
        fig.scatter("x", "y", source=self.src_pick, size=10, color="#b00020")
        self.curve_fig_pane.objects = [pn.pane.Bokeh(fig)]
        self.curve_inputs = n_inputs

    def _draw_curve(self) -> None:
        s = self.s
        n_inputs = len(s.controller.system.inputs)
        if n_inputs != self.curve_inputs:
            self._curve_figure(n_inputs)
        out = s.curve()
        e_pick, de_pick = self.pick_e.value, self.pick_de.value
        if n_inputs == 1:
            e, u = out
            data = {"e": e, "u": u}
            for name, c in self.s.baselines.items():
                if hasattr(c, "curve") and len(c.system.inputs) == 1:
                    data[name] = c.curve(e)
            self.src_curve.data = data
            self.src_pick.data = {"x": [e_pick], "y": [s.firing(e_pick)[2]]}
        else:
            e, de, U = out
            self.surface_mapper.low, self.surface_mapper.high = float(U.min()), float(U.max())
            self.src_surface.data = {"image": [U], "x": [e[0]], "y": [de[0]],
                                     "dw": [e[-1] - e[0]], "dh": [de[-1] - de[0]]}  # fmt: skip
            self.src_pick.data = {"x": [e_pick], "y": [de_pick]}

    def _build_firing(self) -> None:
        self.pick_e = pn.widgets.FloatInput(
            name="error e [V]", value=0.1, step=0.01, width=150, css_classes=["fs-pick-e"]
        )
        self.pick_de = pn.widgets.FloatInput(
            name="error rate ė [V/s]", value=0.0, step=0.1, width=150
        )
        self.pick_out = pn.pane.HTML("", css_classes=["fs-command"])
        self.src_fire = ColumnDataSource({"rule": [], "w": []})
        self.fig_fire = figure(title="rule firing strengths at the picked input", width=TAB_WIDTH,
                               height=260, x_range=FactorRange(), y_range=Range1d(0, 1.05),
                               tools="")  # fmt: skip
        self.fig_fire.vbar(x="rule", top="w", source=self.src_fire, width=0.8, color=_colour(0))
        self.fig_fire.xaxis.major_label_orientation = 0.9
        for w in (self.pick_e, self.pick_de):
            w.param.watch(lambda ev: self._guard(self._redraw_pick), "value")
        self.firing_box = pn.Column(
            "#### Rule firing at an input", pn.Row(self.pick_e, self.pick_de), self.pick_out,
            pn.pane.Bokeh(self.fig_fire),
        )  # fmt: skip

    def _draw_firing(self) -> None:
        s = self.s
        labels, w, u = s.firing(self.pick_e.value, self.pick_de.value)
        labels = [f"{k + 1}. {text}" for k, text in enumerate(labels)]
        if len(labels) > 12:  # a 7×7 table: the rules that fire, or 49 bars nobody can read
            shown = [k for k, v in enumerate(w) if v > 0]
            labels, w = [labels[k] for k in shown], [w[k] for k in shown]
            self.fig_fire.title.text = (
                f"firing strengths of the rules that fire at the picked input "
                f"({len(shown)} of {len(s.controller.system.rules)})"
            )
        else:
            self.fig_fire.title.text = "rule firing strengths at the picked input"
        if list(self.fig_fire.x_range.factors) != labels:
            self.fig_fire.x_range.factors = labels
        self.src_fire.data = {"rule": labels, "w": list(w)}
        rate = f", ė = {self.pick_de.value:g} V/s" if len(s.controller.system.inputs) == 2 else ""
        # form pi integrates the fuzzy output: what the map gives is the command's rate
        what, unit = (
            ("command rate du/dt", "V/s") if s.controller.form == "pi" else ("command u", "V")
        )
        self.pick_out.object = (
            f"<span id='fs-command'>{what} = <b>{u:.4g} {unit}</b> at "
            f"e = {self.pick_e.value:g} V{rate}</span>"
        )
        c = s.controller
        for role, (*_, picked) in self.mf_figs.items():
            if role == "input":
                picked.location = c.input_gain * self.pick_e.value
            elif role == "rate":
                picked.location = c.rate_gain * self.pick_de.value

    def _redraw_pick(self) -> None:
        with pn.io.hold():
            self._draw_firing()
            self._draw_curve()

    # ================================================================ rules
    def _draw_rules(self) -> None:
        s = self.s
        grid = s.rule_grid()
        system = s.controller.system
        outs = ["", *(t.name for t in system.output.terms)]
        widgets: list = []
        if grid is not None:
            import pandas as pd

            rows = [t.name for t in system.inputs[0].terms]
            if len(system.inputs) == 1:
                cols = [system.output.name]
            else:
                cols = [t.name for t in system.inputs[1].terms]
            frame = pd.DataFrame(
                grid, index=pd.Index(rows, name=system.inputs[0].name), columns=cols
            )
            table = pn.widgets.Tabulator(
                frame,
                editors={c: {"type": "list", "values": outs} for c in cols},
                show_index=True,
                sortable=False,
                selectable=False,
                css_classes=["fs-rule-table"],
            )
            table.on_edit(lambda ev: self._guard(self._on_rule_cell, ev, rows, cols))
            title = (
                f"#### Rule table: output term per {system.inputs[0].name} term"
                if len(system.inputs) == 1
                else f"#### Rule table: rows {system.inputs[0].name}, columns {system.inputs[1].name}"
            )
            widgets += [title, table]
        lines = pn.widgets.TextAreaInput(
            name="rule lines ('NB -> NB', 'NS and PS -> Z 0.5', '~Z or PB -> PS'; '-' no condition)",
            value="\n".join(s.rule_lines()),
            height=180,
            width=TAB_WIDTH // 2,
        )
        apply = pn.widgets.Button(name="Apply rule lines", button_type="primary", width=160)
        apply.on_click(lambda ev: self._guard(self._on_rule_lines, lines.value))
        widgets += [pn.Row(lines, apply)]
        self.rules_box.objects = widgets

    def _on_rule_cell(self, ev, rows, cols) -> None:
        self.s.set_rule_cell(int(ev.row), cols.index(ev.column), ev.value or "")
        self.refresh(rules=True)

    def _on_rule_lines(self, text: str) -> None:
        self.s.set_rules(text.splitlines())
        self.refresh(structure=True)

    # ================================================================ sidebar
    def _rig_widgets(self):
        folders = self.s.folders
        rigs = folders.names("rigs")
        current = self.s.rig_path.stem
        self.rig_select = pn.widgets.Select(
            name="rig", options=sorted({*rigs, current}), value=current, width=135
        )
        self.scenario_select = pn.widgets.Select(
            name="scenario", options=list(self.s.rig.scenarios), value=self.s.scenario, width=135
        )

        def on_rig(ev) -> None:
            path = folders.find("rigs", ev.new)
            self.s.set_rig(path if path is not None else self.s.rig_path)
            self.scenario_select.options = list(self.s.rig.scenarios)
            self.scenario_select.value = self.s.scenario
            self.refresh()

        def on_scenario(ev) -> None:
            if ev.new != self.s.scenario and ev.new in self.s.rig.scenarios:
                self.s.set_scenario(ev.new)
                self.refresh()

        self.rig_select.param.watch(lambda ev: self._guard(on_rig, ev), "value")
        self.scenario_select.param.watch(lambda ev: self._guard(on_scenario, ev), "value")
        return pn.Column(pn.pane.Markdown("### Rig"), pn.Row(self.rig_select, self.scenario_select))

    def _draw_design(self) -> None:
        s = self.s
        cards = []
        for role in s.roles():
            design = s.design(role)
            var = s.variable(role)
            if design is None:
                cards.append(pn.pane.Markdown(
                    f"**{role} {var.name}**: explicit terms (edit breakpoints in the "
                    "membership-function tab, or drag them)"
                ))  # fmt: skip
                if role in s.designs:
                    back = pn.widgets.Button(name=f"Back to the {role}'s seven-term design")
                    back.on_click(lambda ev, role=role: self._guard(self._restore, role))
                    cards.append(back)
                continue
            lo, hi = design["range"]
            span = hi - lo
            widgets = []
            for k, d in enumerate(design["increments"]):
                label = "left shoulder" if k == 0 else "right shoulder" if k == 7 else f"gap {k}"
                widgets.append(self._slider(f"{role} increment {k} ({label})", d, 0.05, max(3.0, d),
                                            0.01, lambda v, role=role, k=k: s.set_design(role, "increments", v, k)))  # fmt: skip
            widgets.append(self._slider(f"{role} reshape γ", design["reshape"], 0.25, max(4.0, design["reshape"]), 0.01,
                                        lambda v, role=role: s.set_design(role, "reshape", v)))  # fmt: skip
            t = design["translate"]
            widgets.append(self._slider(f"{role} translate δ", t, min(-span / 2, t), max(span / 2, t), span / 1000,
                                        lambda v, role=role: s.set_design(role, "translate", v)))  # fmt: skip
            cards.append(pn.Card(*widgets, title=f"{role} {var.name} [{lo:g}, {hi:g}]",
                                 collapsed=role != "input", sizing_mode="stretch_width"))  # fmt: skip
        c = s.controller
        gains = [("input", c.input_gain), ("output", c.output_gain)]
        if len(c.system.inputs) == 2:
            gains.insert(1, ("rate", c.rate_gain))
        gain_widgets = [
            self._slider(
                f"gain {which}",
                g,
                min(0.1, g),
                max(5.0, g),
                0.01,
                lambda v, which=which: s.set_gain(which, v),
            )
            for which, g in gains
        ]
        cards.append(pn.Card(*gain_widgets, title="gains", sizing_mode="stretch_width"))
        self.design_box.objects = cards

    def _slider(self, name: str, value: float, lo: float, hi: float, step: float, setter):
        slider = pn.widgets.FloatSlider(
            name=name, value=float(value), start=float(lo), end=float(hi), step=float(step),
            format="0[.]000", sizing_mode="stretch_width",
            css_classes=["fs-slider"],
        )  # fmt: skip

        def changed(ev) -> None:
            setter(ev.new)
            self.refresh()

        slider.param.watch(lambda ev: self._guard(changed, ev), "value")
        return slider

    def _file_widgets(self):
        f = self.s.folders
        self.open_select = pn.widgets.Select(
            name="controller file", options=f.controller_files(), width=195
        )
        open_btn = pn.widgets.Button(name="Open", width=75)
        open_btn.on_click(lambda ev: self._guard(self._open, self.open_select.value))
        self.open_path = pn.widgets.TextInput(name="or a path (project or output folder)", width=195,
                                              placeholder="studies/controllers/flc1_translated.yaml")  # fmt: skip
        open_path_btn = pn.widgets.Button(name="Open path", width=75, css_classes=["fs-open-path"])
        open_path_btn.on_click(lambda ev: self._guard(self._open, self.open_path.value))
        upload = pn.widgets.FileInput(accept=".yaml,.yml,.fis", name="upload", width=280)

        def on_upload(ev) -> None:
            self.s.open_upload(upload.filename, upload.value)
            self.refresh(structure=True)
            self._say(f"opened {upload.filename} from the browser")

        upload.param.watch(lambda ev: self._guard(on_upload, ev), "value")
        self.save_name = pn.widgets.TextInput(
            name=f"save as (in {f.output})",
            value="designed.yaml",
            width=280,
            css_classes=["fs-save-name"],
        )
        save_yaml = pn.widgets.Button(name="Save YAML", width=100, css_classes=["fs-save-yaml"])
        save_fis = pn.widgets.Button(name="Save .fis", width=100)
        save_yaml.on_click(lambda ev: self._guard(self._save, "yaml"))
        save_fis.on_click(lambda ev: self._guard(self._save, "fis"))
        return pn.Column(
            pn.pane.Markdown("### Controller files"),
            pn.Row(self.open_select, open_btn),
            pn.Row(self.open_path, open_path_btn),
            upload,
            self.save_name,
            pn.Row(save_yaml, save_fis),
        )

    def _open(self, name: str) -> None:
        self.s.open_file(name)
        self.refresh(structure=True)
        self._say(f"opened {self.s.folders.label(Path(self.s.source))}")

    def _save(self, kind: str) -> None:
        name = self.save_name.value
        if kind == "fis":
            name = str(Path(name).with_suffix(".fis"))
            path = self.s.save_fis(name)
        else:
            name = str(Path(name).with_suffix(".yaml")) if Path(name).suffix != ".yaml" else name
            path = self.s.save_yaml(name)
        self.open_select.options = self.s.folders.controller_files()
        self._say(f"saved {path}")

    def _study_widgets(self):
        s = self.s
        studies = s.study_files()
        self.study_select = pn.widgets.Select(
            name="study", options=studies, width=160, css_classes=["fs-study"],
            value=MAIN_STUDY if MAIN_STUDY in studies else None,
        )  # fmt: skip
        self.storage_input = pn.widgets.TextInput(
            name="storage URL", width=280, css_classes=["fs-storage"]
        )
        self.study_select.param.watch(lambda ev: self._guard(self._pick_study, ev.new), "value")
        open_btn = pn.widgets.Button(name="Open storage", width=105, css_classes=["fs-open-study"])
        open_btn.on_click(lambda ev: self._guard(self._open_study))
        import pandas as pd

        self.trials_table = pn.widgets.Tabulator(pd.DataFrame(), selectable="checkbox", width=280, stylesheets=[DENSE_TABLE], css_classes=["fs-trials"],
                                                 height=240, show_index=False, disabled=True)  # fmt: skip
        compare = pn.widgets.Button(name="Compare selected", width=135, css_classes=["fs-compare"])
        compare.on_click(lambda ev: self._guard(self._compare))
        load = pn.widgets.Button(name="Edit first selected", width=135)
        load.on_click(lambda ev: self._guard(self._load_trial))
        clear = pn.widgets.Button(name="Clear comparison", width=135)
        clear.on_click(lambda ev: self._guard(self._clear_compare))
        dash = pn.widgets.Button(name="optuna-dashboard", width=135)
        dash.on_click(lambda ev: self._guard(self._dashboard))
        self.dash_link = pn.pane.HTML("")
        self.trials_note = pn.pane.HTML("", width=280)
        if self.study_select.value:
            self._guard(self._pick_study, self.study_select.value)
        return pn.Column(
            pn.pane.Markdown("### Tuning study"),
            pn.Row(self.study_select, open_btn),
            self.storage_input,
            self.trials_table,
            self.trials_note,
            pn.Row(compare, load),
            pn.Row(clear, dash),
            self.dash_link,
        )

    def _pick_study(self, study: str | None) -> None:
        """A study picked (or preselected when the page opens): its default storage, and its
        trials listed at once when that storage holds any (else a line saying how to get some)."""
        self.storage_input.value = self.s.default_storage(study) if study else ""
        try:
            self._open_study()
        except FuzzyservoError as exc:
            self.study = None
            self.trials_table.value = self.trials_table.value.iloc[0:0]
            self.trials_note.object = f"<div id='fs-trials-note' class='fs-error'>{_esc(exc)}</div>"

    def _open_study(self) -> None:
        import pandas as pd

        view = self.s.open_study(self.study_select.value, self.storage_input.value)
        self.study = view
        rows = [{"trial": t.number, **{f"value{k}" if k else "value": _short(v) for k, v in enumerate(t.values)},
                 "status": t.status, **{p: _short(v) for p, v in t.params.items()}}
                for t in view.trials]  # fmt: skip
        self.trials_table.value = pd.DataFrame(rows)
        note = f"{view.spec.name}: trials {view.counts}; the best {len(view.trials)} listed"
        self.trials_note.object = f"<div id='fs-trials-note'>{_esc(note)}</div>"
        self._say(f"{note} (storage {view.url})")

    def _selected_trials(self):
        if self.study is None:
            raise FuzzyservoError("open a study's storage first")
        picked = [self.study.trials[i] for i in self.trials_table.selection]
        if not picked:
            raise FuzzyservoError("select trials in the table first (tick their boxes)")
        return picked

    def _compare(self) -> None:
        self.s.compare_trials(self.study, self._selected_trials()[:MAX_COMPARED])
        self.refresh()
        self._say(f"comparing trials {', '.join(self.s.compared)} of {self.study.spec.name}")

    def _clear_compare(self) -> None:
        self.s.compared = {}
        self.refresh()

    def _load_trial(self) -> None:
        trial = self._selected_trials()[0]
        self.s.load_trial(self.study, trial)
        self.refresh(structure=True)
        self._say(f"editing trial {trial.number} of {self.study.spec.name}")

    def _dashboard(self) -> None:
        url = self.study.url if self.study else None
        if url is None:
            raise FuzzyservoError("open a study's storage first")
        link = start_dashboard(url, self.web_guard.with_port(self.web_guard.port + 1))
        self.dash_link.object = (
            f"<a href='{link}' target='_blank'>optuna-dashboard on {_esc(url)}</a>"
        )

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

    def _restore(self, role: str) -> None:
        self.s.restore_design(role)
        self.refresh(structure=True)

    def _on_breakpoint(self, role: str, table, ev) -> None:
        frame = table.value
        row = frame.iloc[int(ev.row)]
        params = [float(row[c]) for c in ("a", "b", "c", "d") if c in frame and np.isfinite(row[c])]
        was_design = self.s.design(role) is not None
        self.s.set_breakpoints(role, str(row["term"]), params)
        self.refresh(structure=was_design)

    def _on_drag(self, role: str, old, new) -> None:
        if getattr(self, "_setting_points", False):
            return
        old_x, new_x = list(old.get("x", [])), list(new.get("x", []))
        if len(old_x) != len(new_x):  # a point deleted (Backspace): terms keep their corners
            self._drawn_vars.pop(role, None)
            self._guard(self._draw_mf)
            return
        moved = [k for k, (a, b) in enumerate(zip(old_x, new_x, strict=True)) if a != b]
        if not moved:
            return
        k = moved[0]
        term_name, j = new["term"][k], int(new["k"][k])
        var = self.s.variable(role)
        term = var.terms[var.index(term_name)]
        params = list(term.params)
        params[j] = float(new_x[k])
        # a breakpoint dragged past its neighbours takes them along, so the shape stays valid
        for m in range(j + 1, len(params)):
            params[m] = max(params[m], params[j])
        for m in range(j):
            params[m] = min(params[m], params[j])
        was_design = self.s.design(role) is not None

        def apply() -> None:
            self.s.set_breakpoints(role, term_name, params)
            self.refresh(structure=was_design)

        self._guard(apply)

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


# ==================================================================== helpers
def _column(*figs):
    from bokeh.layouts import column

    return column(*figs)


def _short(value: float) -> float:
    """A number for the trials table: 4 significant digits, so the columns stay narrow."""
    return float(f"{value:.4g}")


def _label_align(x: float, low: float, high: float) -> str:
    """A term's name centred on its peak, except at a range end, where centring would cut it."""
    edge = 0.02 * (high - low)
    return "left" if x <= low + edge else "right" if x >= high - edge else "center"


def _set_legend(fig, renderer, label: str) -> None:
    for item in fig.legend.items if fig.legend else []:
        if renderer in item.renderers:
            item.label = {"value": label}
            return
    from bokeh.models import LegendItem

    if fig.legend:
        fig.legend.items.append(LegendItem(label=label, renderers=[renderer]))


def _breakpoint_frame(var):
    import pandas as pd

    rows = []
    for t in var.terms:
        row = {"term": t.name, "shape": t.shape}
        for name, p in zip(("a", "b", "c", "d"), t.params, strict=False):
            row[name] = round(float(p), 6)
        rows.append(row)
    frame = pd.DataFrame(rows)
    for c in ("a", "b", "c", "d"):
        if c not in frame:
            frame[c] = np.nan
    return frame[["term", "shape", "a", "b", "c", "d"]]


def _cut(text: str, limit: int) -> str:
    return text if len(text) <= limit else f"{text[: limit - 1]}…"


def _esc(text: str) -> str:
    import html

    return html.escape(str(text), quote=True)


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
