"""What the designer page lets a user change, each change an action on its session: the
sidebar (rig and scenario, the seven-term designs and gains, controller files, a tuning
study's trials and optuna-dashboard) and the edits made on the figures and tables
(dragged breakpoints, breakpoint and rule table cells, rule lines).

:class:`Controls` is mixed into :class:`~fuzzyservo.designer.app.Designer`, which holds
the session and the update cycle (``refresh``, ``_guard``, ``_say``) these methods call.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import panel as pn

from fuzzyservo.designer._style import DENSE_TABLE, MAX_COMPARED, _esc
from fuzzyservo.designer.guard import Guard
from fuzzyservo.designer.session import Session, StudyView
from fuzzyservo.designer.web import start_dashboard
from fuzzyservo.errors import FuzzyservoError
from fuzzyservo.tuning import MAIN_STUDY


class Controls:
    """The sidebar's widgets and the page's edits; each calls the session, then ``refresh``."""

    s: Session
    study: StudyView | None
    web_guard: Guard

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

    # ================================================================ edits on the figures
    def _on_rule_cell(self, ev, rows, cols) -> None:
        self.s.set_rule_cell(int(ev.row), cols.index(ev.column), ev.value or "")
        self.refresh(rules=True)

    def _on_rule_lines(self, text: str) -> None:
        self.s.set_rules(text.splitlines())
        self.refresh(structure=True)

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


def _short(value: float) -> float:
    """A number for the trials table: 4 significant digits, so the columns stay narrow."""
    return float(f"{value:.4g}")
