"""Bounded input: a few bytes of input never ask for gigabytes, a traceback or a
megabyte error line.

YAML alias bombs ("billion laughs") and 20,000-deep nesting in a rig, controller or
study file, and in a designer upload; universe points, lookup tables, sampled plants and
measured records past their stated limits (``fuzzyservo/limits.py``); a long value
echoed in a message is cut to an excerpt. Each is one line (exit status 2 on the command
line) that names the file or option, the limit and the fix.
"""

from __future__ import annotations

import json
import resource
import subprocess
import sys
import textwrap

import numpy as np
import pytest
import yaml
from bad_inputs import alias_bomb, nested, study, with_value
from support import TESTS, shipped

from fuzzyservo.cli import main
from fuzzyservo.errors import ConfigError, DataError, excerpt
from fuzzyservo.io._yaml import parse_yaml
from fuzzyservo.limits import (
    MAX_LUT_ENTRIES,
    MAX_PLANT_SAMPLES,
    MAX_POINTS,
    MAX_RECORD_SAMPLES,
    MAX_SAMPLE_POINTS,
    MAX_YAML_DEPTH,
    YAML_ALIAS_FLOOR,
)

SHORT = 400  # characters an error line about a huge input may have at most


def _one_line(capsys, argv: list[str]) -> str:
    """Run the command line; it must fail with exit 2 and one short line on stderr."""
    code = main(argv)
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.strip()]
    assert code == 2, err[:2000]
    assert len(lines) == 1, err[:2000]
    assert lines[0].startswith("fuzzyservo: error: "), lines[0][:2000]
    assert len(lines[0]) < SHORT, f"{len(lines[0])} characters: {lines[0][:2000]}"
    return lines[0]


# -- YAML: alias bombs and deep nesting ----------------------------------------------------
def _files(value: str) -> dict[str, str]:
    """A rig, a controller and a study file whose first key holds ``value``."""
    return {
        "rig": with_value(shipped("dinca_cylinder").read_text(), "name: dinca_cylinder", value),
        "controller": with_value(
            shipped("p_k10", "studies/controllers").read_text(), "gain: 10", value
        ),
        "study": with_value(study(), "name: dinca_flc", value),
    }


def _argv(kind: str, path: str, out: str) -> list[str]:
    return {
        "rig": ["simulate", path, "p_k10", "--out", out],
        "controller": ["simulate", "dinca_cylinder", path, "--out", out],
        "study": ["tune", path, "--trials", "1", "--out", out],
    }[kind]


@pytest.mark.parametrize("kind", ["rig", "controller", "study"])
@pytest.mark.parametrize(
    "label, value, words",
    [
        ("bomb of 6 levels", alias_bomb(6), ("aliases", f"{YAML_ALIAS_FLOOR:,} nodes")),
        ("bomb of 9 levels", alias_bomb(9), ("aliases", f"{YAML_ALIAS_FLOOR:,} nodes")),
        ("20,000 deep", nested(20_000), (f"deeper than {MAX_YAML_DEPTH} levels",)),
    ],
)
def test_alias_bombs_and_deep_nesting_are_one_short_line(
    kind, label, value, words, tmp_path, capsys
):
    path = tmp_path / f"{kind}.yaml"
    path.write_text(_files(value)[kind], encoding="utf-8")
    line = _one_line(capsys, _argv(kind, str(path), str(tmp_path / "out")))
    assert str(path) in line and "line " in line and "column " in line, line
    assert all(w in line for w in words), line
    assert not (tmp_path / "out").exists()


def test_a_designer_upload_of_a_bomb_is_refused_in_little_memory(tmp_path):
    """What the designer's upload calls (``Session.open_upload`` →
    ``controller_data_from_text`` → ``parse_yaml``) on bombs of a few hundred bytes like
    the 445-byte upload that killed the designer process, and on deep nesting: a short
    ConfigError each, in a process whose peak memory hardly grows (capped at 2 GB in case
    it would)."""
    controller = shipped("p_k10", "studies/controllers").read_text()
    uploads = {
        "bomb6.yaml": with_value(controller, "gain: 10", alias_bomb(6)),
        "bomb9.yaml": with_value(controller, "gain: 10", alias_bomb(9)),
        "bare9.yaml": f"a: {alias_bomb(9)}\n",
        "deep.yaml": with_value(controller, "gain: 10", nested(20_000)),
        "deep_block.yaml": "a:\n" + "".join("  " * k + "- \n" for k in range(1, 5_000)),
    }
    assert len(uploads["bare9.yaml"]) < 500  # 9**9 strings in under 500 bytes
    (tmp_path / "uploads.json").write_text(json.dumps(uploads), encoding="utf-8")
    script = textwrap.dedent(
        f"""
        import json
        from fuzzyservo.errors import ConfigError
        from fuzzyservo.io.controllers import controller_data_from_text

        def peak():
            return int(open("/proc/self/status").read().split("VmHWM:")[1].split()[0])

        uploads = json.loads(open({str(tmp_path / "uploads.json")!r}).read())
        before = peak()
        for name, text in uploads.items():
            try:
                controller_data_from_text(text, name)
                print("accepted", name)
            except ConfigError as exc:
                print(str(exc).replace("\\n", " "))
        print(peak() - before)
        """
    )

    def cap() -> None:
        resource.setrlimit(resource.RLIMIT_AS, (2 << 30, 2 << 30))

    done = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, preexec_fn=cap, timeout=300
    )
    assert done.returncode == 0, done.stderr[-3000:]
    *lines, grown_kb = done.stdout.splitlines()
    assert len(lines) == len(uploads), lines
    for name, line in zip(uploads, lines, strict=True):
        assert line.startswith(f"{name}: line "), line
        assert len(line) < SHORT, line
    assert int(grown_kb) < 50 * 1024, f"peak memory grew by {int(grown_kb) / 1024:.0f} MB"


def test_yaml_within_the_limits_reads_as_before():
    """Aliases that repeat a block a few times, merge keys and 100 levels of nesting are
    fine; a loop and a scalar Python cannot build are one located line."""
    text = "base: &b {p: 1, q: [1, 2]}\nc: *b\nd: {<<: *b, r: 3}\ne: [*b, *b, *b]\n"
    data = parse_yaml(text, "ok.yaml")
    assert data["c"] == {"p": 1, "q": [1, 2]} and data["d"] == {"p": 1, "q": [1, 2], "r": 3}
    # the top-level mapping is the first of the levels
    assert parse_yaml(f"a: {nested(MAX_YAML_DEPTH - 1)}", "deep.yaml")["a"]
    for text, words in (
        (f"a: {nested(MAX_YAML_DEPTH)}", ("line 1, column 103", "deeper than 100")),
        ("a: &x [1, *x]\n", ("line 1, column 11", "*x", "remove the alias")),
        ("a: &x {b: *x}\n", ("*x",)),
        ("a: 2020-13-45\n", ("line 1, column 4", "'2020-13-45'", "month must be in 1..12")),
        ("a: " + "1" * 5000 + "\n", ("line 1, column 4", "(5,000 characters)")),
    ):
        with pytest.raises(ConfigError) as err:
            parse_yaml(text, "bad.yaml")
        message = str(err.value)
        assert message.startswith("bad.yaml: ") and len(message) < SHORT, message
        assert all(w in message for w in words), message


# -- values echoed in messages ---------------------------------------------------------------
def test_excerpt_is_the_repr_of_a_short_value_and_a_cut_one_of_a_long_value():
    for value in ("abc", [1, 2.5, (3,)], {"a": [None, True]}, set(), frozenset({1}), b"x", 7):
        assert excerpt(value) == repr(value)
    cut = excerpt("g" * 100_000)
    assert cut == "'" + "g" * 58 + "… (100,000 characters)"
    assert excerpt(list(range(5000))).endswith("… (5,000 items)")
    # a structure shared like an alias bomb's: 9**12 leaves, only the start is rendered
    bomb: list = ["lol"] * 9
    for _ in range(11):
        bomb = [bomb] * 9
    assert len(excerpt(bomb)) < 80
    assert excerpt(10**5000) == "<a whole number too long to write>"


def test_a_long_value_in_a_file_is_cut_in_the_message(tmp_path, capsys):
    text = shipped("p_k10", "studies/controllers").read_text()
    path = tmp_path / "c.yaml"
    path.write_text(text.replace("gain: 10", f"gain: {'g' * 100_000}"), encoding="utf-8")
    line = _one_line(capsys, ["simulate", "dinca_cylinder", str(path)])
    assert "gain: must be a number" in line and "(100,000 characters)" in line, line
    # a 100,000-character unit: refused before Python's parser sees it
    rig = yaml.safe_load(shipped("dinca_cylinder").read_text())
    mass = rig["plant"]["components"]["cylinder"]["parameters"]["piston_mass"]
    mass["unit"] = "-" * 100_000 + "kg"
    path = tmp_path / "rig.yaml"
    path.write_text(yaml.safe_dump(rig), encoding="utf-8")
    line = _one_line(capsys, ["simulate", str(path), "p_k10", "--out", str(tmp_path / "o")])
    assert "piston_mass" in line and "100,002 characters" in line, line


# -- sizes ------------------------------------------------------------------------------------
def test_universe_points_are_bounded_in_every_format(tmp_path, capsys):
    data = yaml.safe_load(shipped("flc1_translated", "studies/controllers").read_text())
    for key, value, most in (
        ("points", 10**9, MAX_POINTS),
        ("points", 2.5, MAX_POINTS),
        ("sample_points", 10**9, MAX_SAMPLE_POINTS),
    ):
        path = tmp_path / f"{key}.yaml"
        path.write_text(yaml.safe_dump({**data, key: value}), encoding="utf-8")
        line = _one_line(capsys, ["show", str(path), "--out", str(tmp_path / "o")])
        assert f"{key}: must be a whole number from 3 to {most:,}" in line, line
    fis = (TESTS / "data" / "tipper.fis").read_text()
    for text, words in (
        (f"% fuzzyservo: points=1000000000\n{fis}", ("points", f"{MAX_POINTS:,}")),
        (f"% fuzzyservo: points={'9' * 5000}\n{fis}", ("points", "(5,000 characters)")),
        (
            fis.replace("[Input1]\n", "[Input1]\n% fuzzyservo: points=5001\n"),
            ("Input1.points", f"{MAX_POINTS:,}"),
        ),
        (
            f"% fuzzyservo: sample_points=100001\n{fis}",
            ("sample_points", f"{MAX_SAMPLE_POINTS:,}"),
        ),
    ):
        path = tmp_path / "x.fis"
        path.write_text(text, encoding="utf-8")
        line = _one_line(capsys, ["show", str(path), "--out", str(tmp_path / "o")])
        assert all(w in line for w in words), line
    fcl = tmp_path / "x.fcl"
    main(["export", str(TESTS / "data" / "tipper.fis"), "--fcl", str(fcl)])
    capsys.readouterr()
    fcl.write_text(fcl.read_text().replace("points=201", "points=1000000000"), encoding="utf-8")
    line = _one_line(capsys, ["show", str(fcl), "--out", str(tmp_path / "o")])
    assert "points" in line and f"{MAX_POINTS:,}" in line, line


def test_a_two_input_controller_at_the_points_limit_builds_in_bounded_memory():
    """The coverage check visits points² input pairs block by block: 2,000 points (4
    million pairs) needed 2.3 GB at once before; now a few blocks of 65,536."""
    script = textwrap.dedent(
        f"""
        import sys
        import yaml
        sys.path.insert(0, {str(TESTS)!r})
        from fuzzyservo.io.controllers import controller_from_data
        from support import shipped

        def peak():
            return int(open("/proc/self/status").read().split("VmHWM:")[1].split()[0])

        data = yaml.safe_load(shipped("fpi_ehs160", "studies/controllers").read_text())
        controller_from_data(dict(data, points=201), "x.yaml")
        before = peak()
        controller_from_data(dict(data, points=2000), "x.yaml")
        print(peak() - before)
        """
    )
    done = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=300
    )
    assert done.returncode == 0, done.stderr[-3000:]
    assert int(done.stdout.split()[-1]) < 200 * 1024, done.stdout


def test_lookup_tables_and_sampled_plants_are_bounded(tmp_path, capsys):
    side = round(MAX_LUT_ENTRIES**0.5)
    for controller, lut, most in (
        ("fpi_ehs160", 1_000_000_000, side),
        ("fpi_ehs160", side + 1, side),
        ("flc1_translated", MAX_LUT_ENTRIES + 1, MAX_LUT_ENTRIES),
    ):
        out = tmp_path / "c"
        line = _one_line(capsys, ["export", controller, "--c", str(out), "--lut", str(lut)])
        assert f"--lut: {lut:,} points per input" in line and f"at most {most:,} for" in line, line
        assert not out.exists()
    line = _one_line(capsys, ["robustness", "dinca_cylinder", "p_k10", "--samples", "1000000000"])
    assert "--samples" in line and f"{MAX_PLANT_SAMPLES:,}" in line, line
    data = yaml.safe_load(shipped("dinca_robust", "studies").read_text())
    data["uncertainty"]["samples"] = 10**9
    data["rig"] = str(shipped(data["rig"]))
    for key in ("controller", "baseline"):
        data[key] = str(
            shipped(data[key].split("/")[-1].removesuffix(".yaml"), "studies/controllers")
        )
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    line = _one_line(capsys, ["tune", str(path), "--trials", "1", "--out", str(tmp_path / "o")])
    assert "uncertainty.samples" in line and f"{MAX_PLANT_SAMPLES:,}" in line, line


def test_a_record_longer_than_a_run_is_refused(tmp_path):
    """A CSV row past the limit stops the reading there; a compressed .mat vector past it
    is refused from its header, before it is unpacked."""
    from fuzzyservo.io.measured import read_measured

    path = tmp_path / "long.csv"
    with path.open("w") as fh:
        fh.write("t_s,y_cm\n")
        fh.writelines("0,0\n" for _ in range(MAX_RECORD_SAMPLES + 1))
    with pytest.raises(DataError) as err:
        read_measured(path)
    line = str(err.value)
    assert f"row {MAX_RECORD_SAMPLES + 2}: more than the {MAX_RECORD_SAMPLES:,}" in line, line

    import scipy.io

    mat = tmp_path / "long.mat"
    scipy.io.savemat(mat, {"t_s": np.zeros(50_000_000, dtype=np.uint8)}, do_compression=True)
    assert mat.stat().st_size < 1_000_000
    with pytest.raises(DataError, match=r"'t_s' has 50,000,000 values, more than the 2,000,000"):
        read_measured(mat)
