"""The command line is a thin layer over the public API (issue 25, item 5): the same
numbers come from Python as from the shell, and the CLI modules stay small and free of
the numeric, optimisation and file-format libraries."""

from __future__ import annotations

import ast
import json
import subprocess
import sys
from pathlib import Path

import pytest
from support import controller_named, rig_named

import fuzzyservo
from fuzzyservo.cli import main

CLI_MODULES = sorted(
    p
    for p in (Path(fuzzyservo.__file__).parent / "cli", Path(fuzzyservo.__file__).parent / "cli.py")
    for p in ([p] if p.suffix == ".py" else p.glob("*.py"))
    if p.exists()
)
FORBIDDEN = {"numpy", "scipy", "optuna", "csv", "yaml", "numba"}
BUDGET = 640  # lines, every CLI module together (parsing, checks of options, printing)


def test_cli_modules_fit_the_line_budget():
    lines = sum(len(p.read_text(encoding="utf-8").splitlines()) for p in CLI_MODULES)
    assert CLI_MODULES and lines <= BUDGET, f"{lines} lines in {[p.name for p in CLI_MODULES]}"


def test_cli_modules_import_no_numerics_optimiser_or_file_format_library():
    for path in CLI_MODULES:
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names = [node.module]
            else:
                continue
            roots = {n.split(".")[0] for n in names}
            assert not roots & FORBIDDEN, f"{path.name}:{node.lineno} imports {roots & FORBIDDEN}"


def test_importing_the_cli_pulls_in_none_of_them():
    code = (
        "import sys, fuzzyservo.cli; "
        f"print(sorted(m for m in {sorted(FORBIDDEN | {'matplotlib'})!r} if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_every_command_has_its_public_function():
    for name in ("compare", "margins", "frequency", "robustness", "calibrate", "benchmark",
                 "export", "evaluate", "fit_valve", "tune", "describe_fuzzy"):  # fmt: skip
        assert name in fuzzyservo.__all__ and callable(getattr(fuzzyservo, name))


def _shell_json(tmp_path: Path, *args: str) -> dict:
    path = tmp_path / "shell.json"
    assert main([*args, "--json", str(path)]) == 0
    return json.loads(path.read_text(encoding="utf-8"))


def test_compare_from_python_equals_the_shell(tmp_path, capsys):
    rig = rig_named("dinca_cylinder")
    controllers = [controller_named("p_k10"), controller_named("flc2_reshaped")]
    result = fuzzyservo.compare(rig, controllers, "steps")
    shell = _shell_json(tmp_path, "compare", "dinca_cylinder", "p_k10", "flc2_reshaped",
                        "--scenario", "steps", "--out", str(tmp_path / "o"))  # fmt: skip
    assert json.loads(result.to_json()) == shell
    assert result.text() in capsys.readouterr().out  # the table the shell printed
    assert list(result) == ["p_k10", "flc2_reshaped"] and result["p_k10"].ok


def test_margins_from_python_equals_the_shell(tmp_path, capsys):
    result = fuzzyservo.margins(rig_named("dinca_cylinder"), controller_named("p_k10"), "steps")
    shell = _shell_json(tmp_path, "margins", "dinca_cylinder", "p_k10", "--scenario", "steps")
    python = json.loads(result.to_json())
    for record in (python, shell):  # wall time of the bisection, not a result
        record.pop("seconds")
    assert python == shell
    assert str(result).splitlines()[1] in capsys.readouterr().out


def test_a_library_error_is_one_line_from_both(capsys):
    with pytest.raises(fuzzyservo.ConfigError, match="unknown scenario 'nope'"):
        fuzzyservo.compare(rig_named("dinca_cylinder"), [controller_named("p_k10")], "nope")
    with pytest.raises(fuzzyservo.ConfigError, match="unknown bench case 'nope'"):
        fuzzyservo.benchmark(["nope"])
    assert main(["margins", "dinca_cylinder", "p_k10", "--scenario", "nope"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "unknown scenario 'nope'" in err[0] and "dinca_cylinder" in err[0]


def test_a_library_error_names_the_argument_and_the_shell_its_option():
    """The library speaks of its own arguments, the command line of its options."""
    from fuzzyservo.executor import make_executor
    from fuzzyservo.workflows import export_file

    with pytest.raises(fuzzyservo.ConfigError, match=r"^cluster: 'nope' is not a Dask"):
        make_executor(cluster="nope")
    with pytest.raises(fuzzyservo.ConfigError, match=r"^fmi: must be 2 or 3, got 4"):
        export_file("flc2_reshaped", fmu="x.fmu", fmi=4)
    with pytest.raises(fuzzyservo.ConfigError) as caught:
        export_file("flc2_reshaped", fmu="x.fmu", sample_time_s=0.0)
    assert str(caught.value) == "sample_time_s: must be > 0 s, got 0.0"
    assert caught.value.as_option() == "--sample-time: must be > 0 s, got 0.0"  # what main prints
    # and bad_inputs.py's "cli calibrate --effects unknown" ("--effects: ...")


def test_evaluate_and_describe_from_python(tmp_path):
    from fuzzyservo.io.paths import find_file

    source = find_file("flc2_reshaped", "studies/controllers", "controller")
    table = tmp_path / "in.csv"
    table.write_text("e,extra\n0.1,1\n-0.5,2\n", encoding="utf-8")
    result = fuzzyservo.evaluate(source, table)
    assert result.outputs.shape == (2, 1) and result.notes[0].startswith("note: column(s)")
    assert result.text().splitlines()[0] == "u"
    assert "1. if e is" in fuzzyservo.describe_fuzzy(controller_named("flc2_reshaped"))


def test_robustness_from_python_equals_the_shell(tmp_path, capsys):
    from support import shipped

    from fuzzyservo.io.studies import load_study
    from fuzzyservo.tuning import MAIN_STUDY

    study = load_study(shipped(MAIN_STUDY, "studies"))
    rig, p_k10 = rig_named("dinca_cylinder"), controller_named("p_k10")
    result = fuzzyservo.robustness(rig, [p_k10], study, samples=2, scenarios=["steps"])
    shell = _shell_json(tmp_path, "robustness", "dinca_cylinder", "p_k10", "--samples", "2",
                        "--scenario", "steps", "--out", str(tmp_path / "o"))  # fmt: skip
    assert json.loads(result.to_json()) == shell
    assert result.text().splitlines()[0] in capsys.readouterr().out
