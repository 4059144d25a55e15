"""The error contract of the command line (C8): option types checked at parse time, one line, exit 2; anything else
is an internal error, one line naming the command and the exception, exit 3; atomic output files."""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys

import numpy as np
import pytest

from acq import argtypes
from app import cli
from calib.errors import RobocalError
from calib.fileio import atomic_path, atomic_write_text


@pytest.mark.parametrize("fn, raw", [
    (argtypes.finite_float, "nan"), (argtypes.finite_float, "inf"), (argtypes.finite_float, "1e400"),
    (argtypes.finite_float, "x"), (argtypes.positive_float, "0"), (argtypes.positive_float, "-5"),
    (argtypes.nonneg_float, "-1"), (argtypes.positive_int, "0"), (argtypes.positive_int, "1.5"),
    (argtypes.nonneg_int, "-1"), (argtypes.any_int, "9" * 4301), (argtypes.seed_int, "-1"),
    (argtypes.int_range(1, 6), "7"), (argtypes.float_range(0, 1, low_open=True), "0"),
])
def test_bad_values_are_refused_with_a_reason(fn, raw):
    with pytest.raises(argparse.ArgumentTypeError, match="must"):
        fn(raw)


@pytest.mark.parametrize("fn, raw, value", [
    (argtypes.finite_float, "-1e300", -1e300), (argtypes.positive_float, "0.5", 0.5), (argtypes.nonneg_int, "0", 0),
    (argtypes.positive_int, " 12 ", 12), (argtypes.float_range(0, 1), "1", 1.0), (argtypes.seed_int, "0", 0),
])
def test_good_values_pass(fn, raw, value):
    assert fn(raw) == value


def test_output_paths_are_checked_before_work(tmp_path):
    assert argtypes.output_file("-") == "-"
    assert argtypes.output_file(str(tmp_path / "a.json"))
    with pytest.raises(argparse.ArgumentTypeError, match="does not exist"):
        argtypes.output_file(str(tmp_path / "missing" / "a.json"))
    with pytest.raises(argparse.ArgumentTypeError, match="is a directory"):
        argtypes.output_file(str(tmp_path))
    assert argtypes.output_dir(str(tmp_path / "new" / "deeper"))
    (tmp_path / "f").write_text("x")
    with pytest.raises(argparse.ArgumentTypeError, match="not a directory"):
        argtypes.output_dir(str(tmp_path / "f"))
    with pytest.raises(argparse.ArgumentTypeError, match="file not found"):
        argtypes.existing_file(str(tmp_path / "nope.csv"))


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes anywhere")
def test_read_only_directory_is_refused(tmp_path):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o500)
    try:
        with pytest.raises(argparse.ArgumentTypeError, match="not writable"):
            argtypes.output_file(str(ro / "x.json"))
    finally:
        ro.chmod(0o700)


def test_atomic_write_leaves_old_content_on_failure(tmp_path):
    out = tmp_path / "out.json"
    atomic_write_text(out, "old")
    with pytest.raises(RuntimeError):
        with atomic_path(out) as tmp:
            tmp.write_text("half")
            raise RuntimeError("crash in the middle")
    assert out.read_text() == "old" and sorted(p.name for p in tmp_path.iterdir()) == ["out.json"]
    atomic_write_text(out, "new")
    assert out.read_text() == "new"
    with pytest.raises(RobocalError, match="cannot write"):
        atomic_write_text(tmp_path / "missing" / "x", "y")


def test_parse_errors_are_one_line(capsys):
    assert cli.main(["fk", "--robot"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("robocal: error: fk: ") and err.count("\n") == 1


def test_last_resort_handler_names_command_and_exception(monkeypatch, capsys):
    def boom(args):
        raise ZeroDivisionError("division by zero")
    from app.commands import fk
    monkeypatch.setattr(fk, "run", boom)
    assert cli.main(["fk", "0", "0", "0", "0", "0", "0"]) == 3
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "'fk'" in err and "ZeroDivisionError" in err and "Traceback" not in err
    assert cli.main(["fk", "0", "0", "0", "0", "0", "0", "--debug"]) == 3
    err = capsys.readouterr().err
    assert "Traceback" in err and err.strip().splitlines()[-1].startswith("robocal: internal error in 'fk'")


def test_exit_codes_through_the_console_script():
    r = subprocess.run([sys.executable, "-m", "app.cli", "fk", "nan", "0", "0", "0", "0", "0"], capture_output=True,
                       text=True, timeout=60)
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "Traceback" not in r.stderr


def test_top_level_help_loads_no_command_module():
    """First contact is fast: ``robocal --help`` lists every command without importing numpy, scipy or the model
    (each command's module is imported only when that command runs)."""
    code = ("import sys, contextlib, io\n"
            "from app.cli import main\n"
            "with contextlib.redirect_stdout(io.StringIO()) as out:\n"
            "    rc = main(['--help'])\n"
            "assert rc == 0 and 'reprocess' in out.getvalue() and 'diagnose' in out.getvalue(), out.getvalue()\n"
            "heavy = [m for m in ('numpy', 'scipy', 'calib.model', 'app.commands.plan') if m in sys.modules]\n"
            "assert not heavy, heavy\n")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr


def test_base_rotation_matches_an_independent_library():
    from scipy.spatial.transform import Rotation

    from calib.angles import rpy_matrix as _rpy_matrix
    from calib.angles import rpy_from_matrix
    rng = np.random.default_rng(3)
    for rpy in rng.uniform([-3.0, -1.5, -3.0], [3.0, 1.5, 3.0], (50, 3)):
        np.testing.assert_allclose(_rpy_matrix(rpy), Rotation.from_euler("xyz", rpy).as_matrix(), atol=1e-12)
        np.testing.assert_allclose(rpy_from_matrix(_rpy_matrix(rpy)), rpy, atol=1e-12)


_BAD_SETUPS = {"garbage": '{"x": 1}', "ruler_int": '{"ruler": 5, "stations": {}}',
               "stations_int": '{"ruler": {"marks_mm": [0, 1000], "placements": [{"C_mm": [0, 0, 0], '
                               '"dir": [1, 0, 0]}]}, "stations": 3, "base_xyz_mm": [0, 0, 0]}'}


@pytest.mark.parametrize("bad", sorted(_BAD_SETUPS))
def test_a_bad_setup_file_is_one_line_wherever_it_is_given(tmp_path, capsys, bad):
    """demo, plan setup (with and without --out), plan check and session --emulate: a damaged set-up file is one line
    naming it (demo and plan setup used to crash with a TypeError, or ignore it)."""
    f = tmp_path / "setup.json"
    f.write_text(_BAD_SETUPS[bad])
    for argv in (["demo", "--db", str(tmp_path / "d.db"), "--setup", str(f)],
                 ["demo", "--resume", "--db", str(tmp_path / "d.db"), "--setup", str(f)],
                 ["plan", "setup", "ruler", "--setup", str(f), "--out", str(tmp_path / "o.json")],
                 ["plan", "setup", "ruler", "--setup", str(f)],
                 ["plan", "check", str(f)],
                 ["session", "--emulate", "--db", str(tmp_path / "s.db"), "--setup", str(f)]):
        assert cli.main(argv) == 2, argv
        err = capsys.readouterr().err.strip()
        assert err.startswith(f"robocal: error: {f}: ") and "\n" not in err, (argv, err)
    assert not (tmp_path / "d.db").exists() and not (tmp_path / "s.db").exists()
    assert not (tmp_path / "o.json").exists()


def test_an_option_that_cannot_apply_is_an_error(tmp_path, capsys):
    """--setup on a resumed demo, on an emulated session, or on plan setup without --out was silently ignored."""
    from app.commands.session import setup_template
    good = tmp_path / "setup.json"
    good.write_text(json.dumps(setup_template()))
    cases = {("demo", "--resume", "--db", str(tmp_path / "d.db"), "--setup", str(good)):
             "demo: --setup cannot change a resumed session's set-up",
             ("plan", "setup", "ruler", "--setup", str(good)): "it needs --out",
             ("session", "--emulate", "--db", str(tmp_path / "s.db"), "--setup", str(good)):
             "--setup does not apply to --emulate"}
    for argv, words in cases.items():
        assert cli.main(list(argv)) == 2, argv
        err = capsys.readouterr().err.strip()
        assert words in err and "\n" not in err, (argv, err)
    assert not (tmp_path / "d.db").exists() and not (tmp_path / "s.db").exists()


def test_a_resumed_session_keeps_its_setup(tmp_path):
    """robocal session resumed with --setup: the same file is fine, another one (or a bad one) is one line, and the
    stored set-up is untouched."""
    import sqlite3

    from app.commands.session import real_builder, setup_template
    theo = ["A=geocom:robocal://geocom?seed=3&station=A", "B=gsi:robocal://gsi?seed=3&station=B"]
    setup = setup_template()
    f = tmp_path / "setup.json"
    f.write_text(json.dumps(setup))
    db = str(tmp_path / "s.db")
    real_builder(db, theo, None, str(f), None, None, ["ruler/p0"])(None).close()
    stored = sqlite3.connect(db).execute("SELECT setup_json FROM session").fetchone()[0]
    real_builder(db, theo, None, str(f), None, None, ["ruler/p0"])         # the same file: resumes
    other = tmp_path / "other.json"
    other.write_text(json.dumps({**setup, "base_xyz_mm": [1.0, 2.0, 3.0]}))
    with pytest.raises(RobocalError, match=r"cannot change a resumed session's set-up"):
        real_builder(db, theo, None, str(other), None, None, ["ruler/p0"])
    other.write_text('{"x": 1}')
    with pytest.raises(RobocalError, match=str(other)):
        real_builder(db, theo, None, str(other), None, None, ["ruler/p0"])
    assert sqlite3.connect(db).execute("SELECT setup_json FROM session").fetchone()[0] == stored
