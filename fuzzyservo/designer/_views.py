"""What the designer page draws from its session: the loop's figures (reference and
position, actuator command with its limits, pressures) and metrics table, and the tabs
of the fuzzy system (membership functions, control curve or surface, rule table, rule
firing at a picked input).

:class:`Views` is mixed into :class:`~fuzzyservo.designer.app.Designer`, which holds the
session and the update cycle (``refresh``, ``_guard``) these methods are called from.
"""

from __future__ import annotations

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

from fuzzyservo.designer._style import (
    MAX_COMPARED,
    REFERENCE_COLOUR,
    TAB_WIDTH,
    TERM_COLOURS,
    WIDTH,
    _colour,
    _esc,
)
from fuzzyservo.designer.session import Session, metrics_rows
from fuzzyservo.display import (
    PRESSURE_COLOURS,
    axis_label,
    metric_units,
    saturated_spans,
    to_display,
)
from fuzzyservo.metrics import METRIC_DOCS


class Views:
    """The figures and tables of the page, built once and redrawn on every change."""

    s: Session

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


def _column(*figs):
    from bokeh.layouts import column

    return column(*figs)


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
