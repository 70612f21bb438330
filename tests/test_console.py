"""What the console tells: the whole result of a study (baseline named, every metric, the
change and its direction), the command's own time, the version, and "did you mean" for
every misspelt name."""

from __future__ import annotations

import re
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from support import DATA

from fuzzyservo import __version__
from fuzzyservo.cli import main
from fuzzyservo.display import change_text
from fuzzyservo.metrics import METRIC_NAMES


@pytest.mark.parametrize(
    ("before", "after", "text"),
    [
        (2.0, 0.5, "-75.0 % better"),
        (0.5, 2.0, "+300.0 % worse"),
        (1.0, 1.0, "same"),
        (0.0, 0.0, "same"),
        (1e-14, 2e-14, "same"),  # rounding noise on both sides
        (0.0, 0.3, "worse (from 0)"),
        (float("nan"), 1.0, "n/a"),
        (None, 1.0, "n/a"),
    ],
)
def test_change_names_its_direction(before, after, text):
    assert change_text(before, after) == text


def test_tune_prints_the_baseline_every_metric_the_change_and_its_own_time(capsys, tmp_path):
    study = tmp_path / "small.yaml"
    study.write_text(
        textwrap.dedent(f"""\
        name: small
        rig: dinca_cylinder
        scenarios: [pulses]
        controller: {(DATA / "studies" / "controllers" / "flc2_reshaped.yaml").as_posix()}
        baseline: p_k10
        parameters:
          input.reshape: {{low: 0.5, high: 4.0, log: true}}
        objective: {{weights: {{settling_time_s: 1}}}}
        trials: 3
        seed: 1
        """)
    )
    assert main(["tune", str(study), "--out", str(tmp_path / "out")]) == 0
    out = capsys.readouterr().out
    assert "lower is better for every metric" in out
    header = next(line for line in out.splitlines() if line.startswith("metric "))
    assert header.split() == ["metric", "baseline", "p_k10", "best", "change"]
    rows = {line.split()[0]: line for line in out.splitlines() if line.split()[:1]
            and line.split()[0] in METRIC_NAMES}  # fmt: skip
    assert set(rows) == set(METRIC_NAMES)  # every metric, the worse ones too
    assert all(re.search(r"(better|worse|same|n/a)$", row) for row in rows.values()), rows
    took = re.search(r"the command took ([\d.]+) (s|min) \(the optimisation ([\d.]+) s\)", out)
    assert took, out[-400:]
    command = float(took[1]) * (60 if took[2] == "min" else 1)
    assert command >= float(took[3])  # the part is inside the whole


def test_version(capsys):
    with pytest.raises(SystemExit) as done:
        main(["--version"])
    assert done.value.code == 0
    assert capsys.readouterr().out.strip() == f"fuzzyservo {__version__}"


def test_the_version_is_the_package_s():
    import tomllib

    pyproject = Path(__file__).resolve().parents[1] / "pyproject.toml"
    assert tomllib.loads(pyproject.read_text())["project"]["version"] == __version__


@pytest.mark.parametrize(
    ("argv", "meant"),
    [
        (["compare", "dinca_cylnder"], "dinca_cylinder"),
        (["compare", "dinca_cylinder", "p_k01"], "p_k10"),
        (["compare", "dinca_cylinder", "--scenario", "stepz"], "steps"),
        (["tune", "dinca_robst"], "dinca_robust"),
        (["show", "flc2_reshapd"], "flc2_reshaped"),
        (["calibrate", "dinca_cylinder", "{data}", "--effects", "coulomb_fricton"],
         "coulomb_friction"),
        (["bench", "--case", "loop_dinca_x"], None),
    ],
)  # fmt: skip
def test_a_misspelt_name_gets_did_you_mean(capsys, argv, meant):
    data = Path(__file__).resolve().parents[1] / "examples" / "run_dinca_friction.csv"
    if "{data}" in argv and not data.is_file():
        pytest.skip("the example record is not shipped here")
    argv = [a.replace("{data}", str(data)) for a in argv]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("fuzzyservo: error:")
    if meant:
        assert f"did you mean {meant!r}?" in err, err


def test_a_misspelt_study_parameter_gets_did_you_mean(capsys, tmp_path):
    study = tmp_path / "typo.yaml"
    text = (DATA / "studies" / "dinca_flc.yaml").read_text()
    assert "gains.output:" in text
    (tmp_path / "controllers").symlink_to(DATA / "studies" / "controllers")  # its references
    study.write_text(text.replace("gains.output:", "gains.outpt:"))
    assert main(["tune", str(study), "--out", str(tmp_path / "o")]) == 2
    assert "did you mean 'gains.output'?" in capsys.readouterr().err


def test_a_misspelt_command_gets_did_you_mean():
    done = subprocess.run(
        [sys.executable, "-m", "fuzzyservo", "comprae"], capture_output=True, text=True
    )
    assert done.returncode == 2
    assert "did you mean 'compare'?" in done.stderr and done.stderr.count("\n") == 1
