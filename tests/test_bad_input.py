"""Every subcommand with bad inputs: exit 2 and one clear line ``robocal: error: ...``; never 3, never a traceback.

The inputs are the kinds issue 17 found crashing or silently accepted: options out of range or non-finite, outputs
into missing directories, files in the wrong encoding or binary, damaged TOML/JSON/CSV and session databases.
Nothing here may reach the last-resort handler (exit 3): that would be a bug to fix at the boundary.
"""
from __future__ import annotations

import json
import shutil
import sqlite3
from importlib import resources
from pathlib import Path

import pytest

from app.cli import main

PUMA = (resources.files("calib") / "data" / "puma560.toml").read_text(encoding="utf-8")
SCENARIO = (resources.files("calib") / "data" / "twin_default.toml").read_text(encoding="utf-8")
Q6 = ["0", "-90", "90", "0", "0", "0"]


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """Good and bad input files, made once."""
    d = tmp_path_factory.mktemp("bad")
    f = {"dir": d, "missing_dir": d / "no" / "such"}
    (d / "ro").mkdir()
    # robot descriptions
    f["robot_latin1"] = d / "latin1.toml"
    f["robot_latin1"].write_bytes(PUMA.replace('name = "waist"', 'name = "Hüfte"').encode("latin-1"))
    f["robot_bigint"] = d / "bigint.toml"
    f["robot_bigint"].write_text(PUMA.replace("encoder_counts_per_rev = 1000", "encoder_counts_per_rev = " + "9" * 40,
                                              1))
    f["robot_ragged"] = d / "ragged.toml"
    f["robot_ragged"].write_text(PUMA.split("[coupling]")[0] + "[coupling]\nmatrix = [[1, 0], [0, 1, 0]]\n")
    f["robot_binary"] = d / "binary.toml"
    f["robot_binary"].write_bytes(b"\x00\x01\x02robot\xff" * 50)
    f["robot_deep"] = d / "deep.toml"
    f["robot_deep"].write_text("x = " + "[" * 5000 + "]" * 5000 + "\n")
    f["robot_3"] = d / "three.toml"
    f["robot_3"].write_text(PUMA.split("[[joint]]")[0] + "[[joint]]" + "[[joint]]".join(PUMA.split("[[joint]]")[1:4])
                            .split("[coupling]")[0])
    # scenarios
    f["scen_latin1"] = d / "scen.toml"
    f["scen_latin1"].write_bytes(("# Szenario für den Zwilling\n" + SCENARIO).encode("latin-1"))
    f["scen_bigint"] = d / "scen_big.toml"
    f["scen_bigint"].write_text(SCENARIO + "\n[extra_table]\nx = " + "1" * 5000 + "\n")
    # pose CSVs
    f["poses"] = d / "poses.csv"
    assert main(["twin", "--poses", "40", "--export", str(f["poses"])]) == 0
    lines = f["poses"].read_text().splitlines()
    f["csv_nan"] = d / "nan.csv"
    f["csv_nan"].write_text("\n".join(lines[:3] + [lines[3].replace(lines[3].split(",")[0], "nan", 1)] + lines[4:]))
    f["csv_bigfield"] = d / "big.csv"
    f["csv_bigfield"].write_text(lines[0] + "\n" + "1" * 200_000 + lines[1][lines[1].index(","):] + "\n")
    f["csv_binary"] = d / "bin.csv"
    f["csv_binary"].write_bytes(b"q1,q2\x00\xff\xfe" * 100)
    f["csv_utf16"] = d / "utf16.csv"
    f["csv_utf16"].write_bytes("\n".join(lines).encode("utf-16"))
    f["csv_metres"] = d / "metres.csv"
    head = lines[0].split(",")
    xi = [head.index(c) for c in "xyz"]
    rows = [r.split(",") for r in lines[1:]]
    for r in rows:
        for i in xi:
            r[i] = str(float(r[i]) / 1000)
    f["csv_metres"].write_text("\n".join([lines[0]] + [",".join(r) for r in rows]) + "\n")
    f["csv_copies"] = d / "copies.csv"
    f["csv_copies"].write_text("\n".join([lines[0]] + [lines[1]] * 30) + "\n")
    f["readings_nan"] = d / "readings.csv"
    f["readings_nan"].write_text("step,procedure,station,target,face,hz_deg,v_deg\nposes/000,poses,A,P,1,nan,90\n")
    # JSON
    f["deep_json"] = d / "deep.json"
    f["deep_json"].write_text("[" * 100_000 + "]" * 100_000)
    f["setup_bad"] = d / "setup.json"
    f["setup_bad"].write_text(json.dumps({"stations": {"L_mm": -1}, "base_xyz_mm": [0, 0], "tool_target_mm": [0, 0, 0],
                                          "ruler": {}}))
    # a model file, then damaged copies
    f["model"] = d / "model.json"
    assert main(["identify", str(f["poses"]), "--out", str(f["model"])]) == 0
    doc = json.loads(f["model"].read_text())
    for name, change in {"model_nan": lambda m: m["parameters"][0].update(value=float("nan")),
                         "model_str": lambda m: m["parameters"][3].update(value="12"),
                         "model_cov": lambda m: m["covariance"].update(matrix=[[1.0, 2.0]]),
                         "model_effect": lambda m: m["effects"].append({"type": "backlash", "joint": 99}),
                         "model_robot": lambda m: m.update(robot_toml="[[joint]]\na_mm = 'x'\n"),
                         "model_huge": lambda m: m["parameters"][5].update(value=1e300)}.items():
        m = json.loads(json.dumps(doc))
        change(m)
        f[name] = d / f"{name}.json"
        f[name].write_text(json.dumps(m))
    # session databases
    f["db"] = d / "good.db"
    assert main(["import", str(f["poses"]), "--db", str(f["db"])]) == 0
    f["db_empty"] = d / "empty.db"
    f["db_empty"].write_bytes(b"")
    f["db_foreign"] = d / "foreign.db"
    sqlite3.connect(f["db_foreign"]).execute("create table t (x)").connection.close()
    for name, sql in {"db_nosession": "DELETE FROM event_log; DELETE FROM operator_input; DELETE FROM step; "
                                      "DELETE FROM device; DELETE FROM session",
                      "db_setup": "UPDATE session SET setup_json = '{\"stations\": [1,'",
                      "db_spec": "UPDATE step SET spec_json = 'nope' WHERE seq = 2"}.items():
        f[name] = d / f"{name}.db"
        shutil.copy(f["db"], f[name])
        con = sqlite3.connect(f[name])
        con.executescript(sql)
        con.close()
    f["db_counts"] = d / "counts.db"
    shutil.copy(f["db"], f["db_counts"])
    con = sqlite3.connect(f["db_counts"])
    con.execute("INSERT INTO device (session_id, role, driver, url, identity_json, opened_unix_s) "
                "VALUES (1, 'tap', 'x', 'x', '{}', 0)")
    con.execute("INSERT INTO encoder_chunk (step_id, attempt, device_id, n_samples, t0_mono_s, seq, t_device_us, "
                "t_mono_s, counts_wire, counts) VALUES (1, 1, 1, 1, 0, x'00', x'00', x'00', x'00', x'934e554d5059ffff')")
    con.commit()
    con.close()
    return f


def _cases(f) -> list[list[str]]:
    d, missing = f["dir"], f["missing_dir"]
    return [
        # options
        ["fk", "1e308", "0", "0", "0", "0", "0"], ["fk", "nan", *Q6[1:]], ["fk", "0", "0"],
        ["compensate", str(f["model"]), "1e308", *Q6[1:]],
        ["plan", "poses", "--tool", "nan", "nan", "nan"], ["plan", "poses", "--count", "-3"],
        ["plan", "poses", "--out", str(missing / "p.csv")], ["plan", "setup", "ruler", "--sigma-arcsec", "0"],
        ["emulate", "tap", "--rate-hz", "0"], ["emulate", "tap", "--rate-hz", "nan"],
        ["emulate", "tap", "--rate-hz", "-5"], ["emulate", "tap", "--rate-hz", "1e308"],
        ["emulate", "gsi", "--stream-hz", "-1"], ["emulate", "geocom", "--duration", "-1"],
        ["emulate", "geocom", "--q-deg", "500", "0", "0", "0", "0", "0"], ["emulate", "geocom", "--tcp", "9" * 4301],
        ["diagnose", str(f["poses"]), "--max-effects", "-1"], ["diagnose", str(f["poses"]), "--alpha", "2"],
        ["reprocess", str(f["db"]), "--mc", "-5"], ["reprocess", str(f["db"]), "--json", str(missing / "r.json")],
        ["twin", "--poses", "5"], ["twin", "--export", str(missing / "t.csv")], ["twin", "--seed", "-1"],
        ["identify", str(f["poses"]), "--effect", "joint_compliance:nan"],
        ["identify", str(f["poses"]), "--effect", "transmission_error:4:nan"],
        ["identify", str(f["poses"]), "--noise-mm", "0"], ["identify", str(f["poses"]), "--out", str(missing / "m")],
        ["identify", str(f["poses"]), "--out", str(d)],
        ["export", str(f["db"]), "--json", str(missing / "e.json")], ["export", str(f["db"])],
        ["demo", "--db", str(missing / "d.db")], ["demo", "--seed", "-4"],
        ["session", "--db", str(missing / "s.db"), "--emulate"], ["session", "--write-setup", str(missing / "s.json")],
        ["import", str(f["poses"]), "--db", str(missing / "i.db")],
        ["import", str(f["poses"]), "--db", str(f["db"])],
        ["import", str(f["poses"]), "--db", str(d / "never.db"), "--resume"],
        # robot and scenario TOML
        ["fk", *Q6, "--robot", str(f["robot_latin1"])], ["fk", *Q6, "--robot", str(f["robot_bigint"])],
        ["fk", *Q6, "--robot", str(f["robot_ragged"])], ["fk", *Q6, "--robot", str(f["robot_binary"])],
        ["fk", *Q6, "--robot", str(f["robot_deep"])], ["fk", *Q6, "--robot", str(d)],
        ["twin", "--scenario", str(f["scen_latin1"])], ["twin", "--scenario", str(f["scen_bigint"])],
        # CSV
        ["identify", str(f["csv_nan"])], ["identify", str(f["csv_bigfield"])], ["identify", str(f["csv_binary"])],
        ["identify", str(f["csv_utf16"])], ["identify", str(f["csv_metres"])], ["identify", str(f["csv_copies"])],
        ["identify", str(f["poses"]), "--robot", str(f["robot_3"])],
        ["diagnose", str(f["csv_metres"]), "--noise-mm", "0.05"], ["diagnose", str(f["csv_copies"]), "--noise-mm", "0.05"],
        ["plan", "poses", "--evaluate", str(f["csv_binary"])],
        ["import", str(f["csv_binary"]), "--db", str(d / "x1.db")],
        ["import", str(f["readings_nan"]), "--db", str(d / "x2.db")],
        ["import", str(f["csv_nan"]), "--db", str(d / "x3.db")],
        ["import", str(f["poses"]), "--db", str(d / "x4.db"), "--setup", str(f["setup_bad"])],
        ["import", str(f["poses"]), "--db", str(d / "x5.db"), "--setup", str(f["deep_json"])],
        # model JSON
        *[["compensate", str(f[k]), *Q6] for k in ("model_nan", "model_str", "model_cov", "model_effect",
                                                    "model_robot", "model_huge", "deep_json", "csv_binary")],
        # session databases
        *[["sessions", str(f[k])] for k in ("db_empty", "db_foreign", "db_nosession")],
        *[["reprocess", str(f[k])] for k in ("db_empty", "db_foreign", "db_nosession", "db_setup", "db_spec",
                                             "db_counts")],
        ["export", str(f["db_setup"]), "--json", str(d / "e1.json")], ["diagnose", str(f["db_empty"])],
        ["demo", "--resume", "--db", str(f["db_empty"])],
    ]


def test_every_bad_input_is_one_line_and_exit_2(files, capsys):
    failures, n = [], 0
    for argv in _cases(files):
        n += 1
        rc = main(argv)
        err = capsys.readouterr().err.strip()
        lines = [ln for ln in err.splitlines() if not ln.startswith("robocal: warning: ")]
        if rc != 2 or len(lines) != 1 or not lines[0].startswith("robocal: error: ") or "Traceback" in err:
            failures.append(f"{' '.join(a[:60] for a in argv)} -> exit {rc}: {err[:300]!r}")
    assert not failures, f"{len(failures)} of {n} bad inputs misbehave:\n" + "\n".join(failures)


def test_nothing_half_made(files):
    """No database or partial file appears where a command refused its input."""
    d = files["dir"]
    assert not list(d.glob("x*.db*")) and not (d / "never.db").exists()
    assert files["db_empty"].stat().st_size == 0          # the advice never writes a schema into a foreign file


def test_good_inputs_still_work(files, capsys, tmp_path):
    """The boundary accepts what it should: a UTF-8 file with a BOM, an import resumed after an interruption."""
    bom = tmp_path / "bom.toml"
    bom.write_bytes(b"\xef\xbb\xbf" + PUMA.encode("utf-8"))
    assert main(["fk", *Q6, "--robot", str(bom), "--json"]) == 0
    csv_bom = tmp_path / "bom.csv"
    csv_bom.write_bytes(b"\xef\xbb\xbf" + files["poses"].read_bytes())
    assert main(["import", str(csv_bom), "--db", str(tmp_path / "b.db")]) == 0
    capsys.readouterr()


def test_forced_implausible_fit_names_its_warnings(files, capsys):
    """--force-implausible fits data in metres but says so on stderr and in the JSON, with the check's name."""
    assert main(["identify", str(files["csv_metres"]), "--force-implausible", "--json"]) == 0
    out = capsys.readouterr()
    codes = [w["code"] for w in json.loads(out.out)["plausibility_warnings"]]
    assert "length_unit" in codes and "robocal: warning: identify: implausible data (length_unit)" in out.err
