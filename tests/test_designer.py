"""The designer's session (no browser): edits, runs, files, folders, studies, the dashboard link.

The page itself is driven in a real browser by ``test_designer_browser.py``.
"""

from __future__ import annotations

import math
import os
import socket
import time
import urllib.parse
import urllib.request

import numpy as np
import pytest
from support import DATA

from fuzzyservo.designer.files import Folders
from fuzzyservo.designer.session import Session, metrics_rows
from fuzzyservo.errors import ConfigError, FuzzyservoError
from fuzzyservo.io.controllers import load_controller
from fuzzyservo.io.fuzzy import fuzzy_controller_data

RIG = DATA / "rigs" / "dinca_cylinder.yaml"
FLC2 = DATA / "studies" / "controllers" / "flc2_reshaped.yaml"


@pytest.fixture
def folders(tmp_path) -> Folders:
    return Folders.make(DATA, tmp_path / "out")


@pytest.fixture
def session(folders) -> Session:
    return Session.open(folders, RIG, FLC2)


def test_folders_refuse_paths_outside_the_project_and_output(folders, tmp_path):
    assert folders.resolve("rigs/dinca_cylinder.yaml") == RIG
    for outside in ("/etc/passwd", "../../../../etc/passwd", "rigs/../../outside.yaml", "~/x"):
        with pytest.raises(ConfigError, match="outside the designer's folders"):
            folders.resolve(outside)
    # a link inside the output folder that points outside is refused too
    folders.output.mkdir(parents=True)
    (tmp_path / "secret.yaml").write_text("kind: fuzzy\n")
    (folders.output / "link.yaml").symlink_to(tmp_path / "secret.yaml")
    with pytest.raises(ConfigError, match="outside"):
        folders.controller_path(str(folders.output / "link.yaml"))
    # writing: the output folder only (not the project)
    assert folders.resolve("a/b.yaml", write=True) == folders.output / "a" / "b.yaml"
    with pytest.raises(ConfigError, match="outside"):
        folders.resolve(str(DATA / "studies" / "x.yaml"), write=True)
    with pytest.raises(ConfigError, match="ends in"):
        folders.controller_path("rigs/dinca_cylinder.json")


def test_a_working_folder_that_holds_the_shipped_files_is_listed_once(tmp_path):
    # run from a checkout, the working folder is where rigs/ and studies/ are shipped
    folders = Folders.make(DATA, tmp_path / "out", DATA)
    assert folders.sources == (DATA.resolve(),)
    files = folders.controller_files()
    assert len(files) == len(set(files)) and "studies/controllers/p_k10.yaml" in files


def test_a_slider_move_changes_the_loop_and_its_metrics(session):
    before = session.run()
    assert before.result.status == "ok"
    names = [r.name for r in session.baseline_runs()]
    assert names == ["p_k10", "flc2_reshaped"]
    session.set_design("input", "reshape", 1.2)
    after = session.run()
    assert after.metrics["settling_time_s"] != before.metrics["settling_time_s"]
    session.set_design("input", "increments", 2.0, index=3)
    session.set_design("output", "translate", 0.1)
    session.set_gain("output", 1.3)
    assert session.data["input"]["increments"][3] == 2.0
    assert session.data["gains"]["output"] == 1.3
    # a slider moves the number a study searches, by its path, through the design itself
    tuned = load_controller(FLC2).with_params(**{"input.reshape": 1.2, "input.increments[3]": 2.0,
                                                 "output.translate": 0.1, "gains.output": 1.3})  # fmt: skip
    assert session.controller.params() == tuned.params()
    rows = metrics_rows([after, *session.baseline_runs()])
    assert [r[0] for r in rows][:2] == ["rise_time_s", "settling_time_s"]
    assert all(len(r) == 4 for r in rows)


def test_bad_edits_are_refused_and_leave_the_last_good_controller(session):
    good = session.data
    with pytest.raises(ConfigError):
        session.set_design("input", "reshape", -1.0)
    with pytest.raises(ConfigError, match="in order"):
        session.set_breakpoints("input", "Z", [0.5, 0.0, -0.5])
    with pytest.raises(ConfigError, match="uncovered"):
        session.set_rules(["Z -> Z"])
    assert session.data is good


def test_breakpoints_make_explicit_terms_and_rules_edit_as_a_table(session):
    z = session.variable("input").terms[3]
    session.set_breakpoints("input", "Z", [z.params[0], 0.05, z.params[2]])
    assert session.design("input") is None
    assert session.data["input"]["terms"]["Z"] == ["trimf", [z.params[0], 0.05, z.params[2]]]
    assert "reshape" in session.designs["input"]
    grid = session.rule_grid()
    assert [row[0] for row in grid] == ["NB", "NM", "NS", "Z", "PS", "PM", "PB"]
    session.set_rule_cell(0, 0, "NM")
    assert session.rule_lines()[0] == "NB -> NM"
    labels, strengths, u = session.firing(0.05)  # the new peak of Z
    assert labels[3] == "Z -> Z" and strengths[3] == pytest.approx(1.0)
    assert math.isfinite(u)
    session.restore_design("input")
    assert session.design("input")["reshape"] == 2.0 and not session.designs


def test_cli_designer_rejects_bad_files_and_a_busy_port_in_one_line(capsys, tmp_path):
    from fuzzyservo.cli import main

    assert main(["designer", "dinca_cylinder", "p_k10", "--out", str(tmp_path)]) == 2
    assert "is a P controller" in capsys.readouterr().err
    assert main(["designer", "no_such_rig", "--out", str(tmp_path)]) == 2
    assert "no rig named 'no_such_rig'" in capsys.readouterr().err
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        assert main(["designer", "--port", str(port), "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("fuzzyservo: error: cannot listen on 127.0.0.1:") and "--port" in err
    assert "Traceback" not in err


def test_save_yaml_and_fis_read_back_as_the_same_controller(session, folders):
    session.set_design("input", "reshape", 1.5)
    yaml_path = session.save_yaml("mine.yaml")
    fis_path = session.save_fis("mine.fis")
    assert yaml_path.parent == folders.output and fis_path.parent == folders.output
    e = np.linspace(-2, 2, 101)
    np.testing.assert_array_equal(load_controller(yaml_path).curve(e), session.controller.curve(e))
    np.testing.assert_allclose(load_controller(fis_path).curve(e), session.controller.curve(e))
    with pytest.raises(ConfigError, match="outside"):
        session.save_yaml("../escaped.yaml")
    assert not (folders.output.parent / "escaped.yaml").exists()
    session.open_file(str(fis_path))  # a .fis opens as explicit terms and rule lines
    assert session.design("input") is None
    np.testing.assert_allclose(session.controller.curve(e), load_controller(fis_path).curve(e))


def test_upload_and_two_input_controllers(session):
    session.open_upload("flc2.yaml", FLC2.read_bytes())
    assert session.controller.name == "flc2_reshaped"
    with pytest.raises(ConfigError, match="ends in"):
        session.open_upload("x.txt", b"")
    pd_file = DATA / "studies" / "controllers" / "fpi_ehs160.yaml"
    session.set_rig(DATA / "rigs" / "ehs160_motor.yaml")
    session.open_file(str(pd_file))
    assert session.roles() == ["input", "rate", "output"]
    e, de, surface = session.curve()
    assert surface.shape == (de.size, e.size)
    assert session.rule_grid() is not None and len(session.rule_grid()[0]) == 7
    assert session.run().result.status == "ok"


def test_controller_data_round_trip_for_a_fis_style_rule_base(tmp_path):
    from fuzzyservo.io.controllers import controller_from_data

    original = load_controller(DATA / "studies" / "controllers" / "fpi_ehs160.yaml")
    data = fuzzy_controller_data(original)
    data["rules"][0] = data["rules"][0].replace(" and ", " or ") + " 0.5"
    rebuilt = controller_from_data(data, "edited")
    assert rebuilt.system.rules[0].connective == "or"
    assert rebuilt.system.rules[0].weight == 0.5
    again = controller_from_data(fuzzy_controller_data(rebuilt), "again")
    assert again.system == rebuilt.system


@pytest.fixture(scope="module")
def study_out(tmp_path_factory):
    from fuzzyservo.io.studies import load_study
    from fuzzyservo.tuning.runner import run_study

    out = tmp_path_factory.mktemp("designer_study")
    spec = load_study(DATA / "studies" / "dinca_flc.yaml")
    run_study(spec, out / "dinca_flc", trials=6, progress=False)
    return out


def test_a_study_storage_lists_its_best_trials_to_compare_and_edit(study_out):
    session = Session.open(Folders.make(DATA, study_out), RIG, FLC2)
    url = f"sqlite:///{study_out / 'dinca_flc' / 'dinca_flc.db'}"
    view = session.open_study("dinca_flc", url)
    assert view.complete == 6 and len(view.trials) == 6
    values = [t.values[0] for t in view.trials if t.status == "ok"]
    assert values == sorted(values)
    session.compare_trials(view, view.trials[:2])
    runs = session.compared_runs()
    assert [r.name for r in runs] == [f"#{t.number}" for t in view.trials[:2]]
    session.load_trial(view, view.trials[0])
    assert session.data["input"]["reshape"] == view.trials[0].params["input.reshape"]
    # a database outside the designer's folders, or one that is not there, is refused
    with pytest.raises(ConfigError, match="outside"):
        session.open_study("dinca_flc", "sqlite:////tmp/elsewhere.db")
    with pytest.raises(ConfigError, match="fuzzyservo tune"):
        session.open_study("dinca_flc", f"sqlite:///{study_out / 'none.db'}")
    assert not (study_out / "none.db").exists()
    with pytest.raises(ConfigError, match="not started with"):
        session.open_study("dinca_flc", "nosuchdb://user@127.0.0.1:1/x")


def test_a_study_default_storage_is_the_working_folders_out(study_out, tmp_path):
    """``tune`` run in the working folder keeps a study in its out/<name>/<name>.db; the
    designer opens that one, never an out/ beside the shipped files (a checkout's own
    runs), and finds none where the working folder has none."""
    import shutil

    work = tmp_path / "work"
    # the whole folder: the study may still sit in the database's write-ahead log
    shutil.copytree(study_out / "dinca_flc", work / "out" / "dinca_flc")
    session = Session.open(Folders.make(DATA, tmp_path / "o", work), RIG, FLC2)
    db = work.resolve() / "out" / "dinca_flc" / "dinca_flc.db"
    assert session.default_storage("dinca_flc") == f"sqlite:///{db}"
    assert session.open_study("dinca_flc").complete == 6
    empty = Session.open(Folders.make(DATA, tmp_path / "o", tmp_path / "empty"), RIG, FLC2)
    with pytest.raises(ConfigError, match="fuzzyservo tune"):
        empty.open_study("dinca_flc")


def test_the_dashboard_link_serves_optuna_dashboard_on_the_same_storage(study_out):
    """The link carries the dashboard's own token; with it (a cookie after the first
    request) the dashboard answers, and it lists the study."""
    pytest.importorskip("optuna_dashboard", reason="pip install optuna-dashboard")
    import http.cookiejar

    from fuzzyservo.designer.guard import Guard
    from fuzzyservo.designer.web import start_dashboard

    url = f"sqlite:///{study_out / 'dinca_flc' / 'dinca_flc.db'}"
    for attempt in range(5):  # a port free a moment ago may be taken by another worker
        with socket.socket() as s:
            s.bind(("127.0.0.1", 0))
            port = s.getsockname()[1]
        try:
            link = start_dashboard(url, Guard.make(port, "127.0.0.1"))
            break
        except FuzzyservoError as exc:
            if "already in use" not in str(exc) or attempt == 4:
                raise
    port = urllib.parse.urlsplit(link).port  # the next one when this process runs another
    assert link.startswith(f"http://127.0.0.1:{port}/?token=")
    opener = urllib.request.build_opener(
        urllib.request.HTTPCookieProcessor(http.cookiejar.CookieJar())
    )
    deadline = time.monotonic() + 30
    while True:
        try:
            opener.open(link, timeout=5).read()  # sets the cookie
            with opener.open(f"http://127.0.0.1:{port}/api/studies", timeout=5) as reply:
                body = reply.read().decode()
            break
        except OSError:
            if time.monotonic() > deadline:
                raise
            time.sleep(0.3)
    assert "dinca_flc" in body


def test_import_fuzzyservo_imports_no_web_framework():
    import subprocess
    import sys

    code = (
        "import sys, fuzzyservo; fuzzyservo.load_rig; import fuzzyservo.designer; "
        "print(sorted({m.split('.')[0] for m in sys.modules} & {'panel', 'bokeh', 'matplotlib'}))"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, env=os.environ
    )
    assert out.stdout.strip() == "[]"
