"""Fuzzy-controller figures: membership functions, control curve and surface, overview."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from fuzzyservo.controllers.fuzzy import FuzzyController, FuzzySystem, SevenTermDesign
from fuzzyservo.controllers.fuzzy.design import macvicar_whelan, table_rules
from fuzzyservo.plots import control_curve_figure, fuzzy_overview_figure, membership_figure, save

TERMS = ["NB", "NM", "NS", "Z", "PS", "PM", "PB"]


@pytest.fixture(scope="module")
def fuzzy_pd():
    e = SevenTermDesign("e", -2.0, 2.0).variable()
    de = SevenTermDesign("de", -20.0, 20.0).variable()
    u = SevenTermDesign("u", -3.0, 3.0).variable()
    system = FuzzySystem("pd", (e, de), u, table_rules(macvicar_whelan()))
    return FuzzyController(system, form="pd", name="fuzzy_pd")


def _saved(fig, path):
    out = save(fig, path)
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    return out


def _texts(ax):
    return [t.get_text() for t in ax.texts]


@pytest.mark.parametrize("which", ["flc1", "flc2"])
def test_membership_figure_one_input(which, request, tmp_path):
    controller = request.getfixturevalue(which)
    fig = membership_figure(controller)
    _saved(fig, tmp_path / f"{which}_mf.png")
    axes = fig.get_axes()
    assert [ax.get_xlabel() for ax in axes] == ["e [V]", "u [V]"]
    assert controller.name in fig.get_suptitle()
    for ax, var in zip(axes, (*controller.system.inputs, controller.system.output), strict=True):
        # one line per term plus the two dashed range edges
        assert len(ax.lines) == len(var.terms) + 2
        assert _texts(ax) == TERMS
        lo, hi = ax.get_xlim()
        assert lo < var.low and hi > var.high


def test_membership_figure_draws_the_sampled_table(flc2):
    """The lines are Variable.table() itself: every breakpoint is a vertex of the plot."""
    ax = membership_figure(flc2).get_axes()[0]
    universe, degrees = flc2.system.inputs[0].table()
    for line, mu in zip(ax.lines, degrees, strict=False):
        np.testing.assert_array_equal(line.get_xdata(), universe)
        np.testing.assert_array_equal(line.get_ydata(), mu)


def test_term_names_sit_at_the_peaks(flc1):
    ax = membership_figure(flc1).get_axes()[1]
    centres = {t.name: t.params[1] for t in flc1.system.output.terms if t.shape == "trimf"}
    for text in ax.texts:
        if text.get_text() in centres:
            assert text.xy[0] == pytest.approx(centres[text.get_text()], abs=1e-9)
            assert text.xy[1] == pytest.approx(1.0)


def test_membership_figure_two_inputs(fuzzy_pd, tmp_path):
    fig = membership_figure(fuzzy_pd)
    _saved(fig, tmp_path / "pd_mf.png")
    assert [ax.get_xlabel() for ax in fig.get_axes()] == ["e [V]", "ė [V/s]", "u [V]"]


def test_control_curve_compares_one_input_controllers(flc1, flc2, tmp_path):
    fig = control_curve_figure(flc1, compare=[flc2])
    _saved(fig, tmp_path / "curves.png")
    (ax,) = fig.get_axes()
    assert (ax.get_xlabel(), ax.get_ylabel()) == ("e [V]", "u [V]")
    legend = [t.get_text() for t in ax.get_legend().get_texts()]
    assert [s.split(" (")[0] for s in legend] == [flc1.name, flc2.name]
    curves = [line for line in ax.lines if line.get_label() in legend]
    assert len(curves) == 2
    for line, controller in zip(curves, (flc1, flc2), strict=True):
        e = np.asarray(line.get_xdata())
        assert e[0] == pytest.approx(-2.0) and e[-1] == pytest.approx(2.0)
        np.testing.assert_allclose(line.get_ydata(), controller.curve(e))
    # u = 0 and e = 0 reference lines
    refs = [line for line in ax.lines if line.get_label().startswith("_")]
    flat = {tuple(np.unique(line.get_ydata())) for line in refs} | {
        tuple(np.unique(line.get_xdata())) for line in refs
    }
    assert (0.0,) in flat


def test_control_curve_marks_the_translated_null_point(flc1):
    """Seed 002 §6: the output terms move by +0.26 V, so u = 0 lies at a negative error."""
    (ax,) = control_curve_figure(flc1).get_axes()
    (label,) = [t.get_text() for t in ax.get_legend().get_texts()]
    crossing = float(label.split("e = ")[1].split(" V")[0].replace("\u2212", "-"))
    assert crossing < 0.0
    assert flc1.curve(np.array([crossing]))[0] == pytest.approx(0.0, abs=1e-2)


def test_control_surface_two_inputs(fuzzy_pd, tmp_path):
    fig = control_curve_figure(fuzzy_pd)
    _saved(fig, tmp_path / "surface.png")
    (ax,) = fig.get_axes()
    assert ax.name == "3d"
    assert (ax.get_xlabel(), ax.get_ylabel(), ax.get_zlabel()) == ("e [V]", "ė [V/s]", "u [V]")
    (surface,) = ax.collections
    assert len(surface.get_paths()) == 40 * 40  # faces of a 41×41 grid


def test_overview_one_input(flc2, tmp_path):
    fig = fuzzy_overview_figure(flc2)
    _saved(fig, tmp_path / "overview.png")
    axes = fig.get_axes()
    assert len(axes) == 3
    assert [ax.get_xlabel() for ax in axes] == ["e [V]", "u [V]", "e [V]"]
    assert axes[2].get_ylabel() == "u [V]"
    assert flc2.name in fig.get_suptitle()


def test_overview_two_inputs(fuzzy_pd, tmp_path):
    fig = fuzzy_overview_figure(fuzzy_pd)
    _saved(fig, tmp_path / "overview_pd.png")
    axes = fig.get_axes()
    assert [ax.name for ax in axes] == ["rectilinear"] * 3 + ["3d"]
    assert [ax.get_xlabel() for ax in axes[:3]] == ["e [V]", "ė [V/s]", "u [V]"]


def test_bad_inputs_are_rejected(flc1, fuzzy_pd, p_k10):
    with pytest.raises(TypeError, match="needs a FuzzyController, got P"):
        membership_figure(p_k10)
    with pytest.raises(TypeError, match="FuzzyController"):
        control_curve_figure(flc1, compare=[p_k10])
    with pytest.raises(ValueError, match=r"\['fuzzy_pd'\] have two inputs"):
        control_curve_figure(flc1, compare=[fuzzy_pd])
    with pytest.raises(ValueError, match="cannot be overlaid"):
        control_curve_figure(fuzzy_pd, compare=[flc1])


def test_import_plots_does_not_import_skfuzzy_control():
    code = (
        "import sys, fuzzyservo.plots; "
        "assert 'skfuzzy.control' not in sys.modules, 'skfuzzy.control was imported'"
    )
    subprocess.run([sys.executable, "-c", code], check=True)
