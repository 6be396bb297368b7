"""CSV log loader (pfbench.plants.datalog) and `pfbench run --data`."""
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from pfbench import models
from pfbench.plants import chamber
from pfbench.cli import main
from pfbench.plants.datalog import load_log, read_log, write_log
from pfbench.errors import DataError

EXAMPLE = Path(__file__).resolve().parents[2] / "reproductions" / "embedded" / "example_log.csv"
GOOD = "time_s,y,u1,u2,t_out\n0,19.5,100,30,19.4375\n1,19.5625,100,30,19.4375\n2,19.625,0,100,19.5\n"


def _write(tmp_path, text, name="log.csv"):
    p = tmp_path / name
    p.write_text(text)
    return p


def test_roundtrip_and_initial_measurement(tmp_path):
    run = chamber.heating_normal(seed=1, duration_s=60)
    p = write_log(tmp_path / "hn.csv", run)
    m = models.get("thermal_inertial")
    tr = load_log(p, m)
    np.testing.assert_allclose(tr.y[:, 0], run.y, atol=1e-12)
    np.testing.assert_allclose(tr.u, np.column_stack([run.u1, run.u2, run.mode]))
    assert np.all(np.isnan(tr.x)) and m.y0 == run.y[0]   # PF starts at y(0), [Embedded] §4.2
    mo = models.get("thermal_outdoor")
    tro = load_log(p, mo)
    np.testing.assert_allclose(tro.y[:, 0], run.y - run.t_out, atol=1e-12)
    assert mo.y0 == pytest.approx(run.y[0] - run.t_out[0]) and mo.t_in0 == run.y[0]


def test_mode_derived_from_u1_when_absent(tmp_path):
    tr = load_log(_write(tmp_path, GOOD), models.get("thermal_inertial"))
    np.testing.assert_array_equal(tr.u[:, 2], [1.0, 1.0, 0.0])
    assert load_log(_write(tmp_path, GOOD), models.get("thermal_rate")).u is None


@pytest.mark.parametrize("text,pattern", [
    ("time_s,y,u2\n0,19.5,30\n", r"log.csv:1: missing column\(s\) u1"),
    (GOOD.replace("1,19.5625,", "1,abc,"), r"log.csv:3: non-numeric value 'abc' in column 'y'"),
    (GOOD.replace("1,19.5625,", "1,,"), r"log.csv:3: non-numeric value '' in column 'y'"),
    (GOOD.replace("\n2,", "\n0.5,"), r"log.csv:4: time not increasing"),
    (GOOD + "3,19.6,0,100,19.5\n7,19.6,0,100,19.5\n", r"log.csv:6: gap in time"),
    (GOOD.replace("\n2,19.625,0,100,19.5", "\n2,19.625,0,100"), r"log.csv:4: expected 5 values, got 4"),
    (GOOD.replace("1,19.5625,", "1,nan,"), r"log.csv:3: non-finite value"),
    ("time_s,y,u1,u2\n", r"no data rows"),
    ("", r"empty log"),
])
def test_bad_logs_raise_one_line_naming_the_line(tmp_path, text, pattern):
    p = _write(tmp_path, text)
    with pytest.raises(DataError, match=pattern) as ei:
        load_log(p, models.get("thermal_inertial"))
    assert "\n" not in str(ei.value)


def test_outdoor_model_needs_t_out(tmp_path):
    p = _write(tmp_path, "time_s,y,u1,u2\n0,19.5,100,30\n1,19.5,100,30\n")
    with pytest.raises(DataError, match="missing column.*t_out"):
        load_log(p, models.get("thermal_outdoor"))


def test_missing_file(tmp_path):
    with pytest.raises(DataError, match="cannot read log"):
        read_log(tmp_path / "nope.csv")


def test_cli_run_on_log_and_bad_log(tmp_path):
    r = CliRunner().invoke(main, ["run", "--model", "thermal_rate", "--data", str(EXAMPLE), "--particles", "50",
                                  "--backend", "numpy", "--json"])
    assert r.exit_code == 0, r.output
    assert '"n_steps": ' in r.output
    good = _write(tmp_path, GOOD, "good.csv")
    args = ["run", "--model", "thermal_inertial", "--data", str(good), "--particles", "20", "--backend", "numpy"]
    r = CliRunner().invoke(main, [*args, "--steps", "2", "--json"])   # the log's first M rows
    assert r.exit_code == 0 and '"n_steps": 2,' in r.output, r.output
    r = CliRunner().invoke(main, [*args, "--steps", "4"])               # was ignored
    assert r.exit_code == 2 and "4 steps, but" in r.output and "has 3 rows" in r.output, r.output
    r = CliRunner().invoke(main, [*args, "--truth-seed", "3"])         # nothing is simulated
    assert r.exit_code == 2 and "--truth-seed" in r.output, r.output
    bad = _write(tmp_path, GOOD.replace("\n2,", "\n0.5,"))
    r = CliRunner().invoke(main, ["run", "--model", "thermal_inertial", "--data", str(bad), "--backend", "numpy"])
    assert r.exit_code == 2
    assert "error:" in r.output and "log.csv:4: time not increasing" in r.output
    r = CliRunner().invoke(main, ["run", "--model", "thermal_inertial", "--data", str(bad), "--backend", "numpy",
                                  "--steps", "2", "--json"])  # the bad row is past the rows asked for
    assert r.exit_code == 0 and '"n_steps": 2,' in r.output, r.output


def test_example_log_is_valid():
    cols = read_log(EXAMPLE)
    assert set(cols) >= {"time_s", "y", "u1", "u2", "t_out", "mode"} and len(cols["y"]) > 100


def test_non_utf8_log_is_one_line_naming_the_file(tmp_path):
    """A log saved as Latin-1 (degree sign as byte 0xb0) used to end in a UnicodeDecodeError
    traceback; now one line naming file, line and byte, exit 2. Catches a decode error that escapes."""
    bad = tmp_path / "latin1.csv"
    bad.write_bytes(GOOD.replace("t_out\n", "t_out # \xb0C\n").encode("latin-1"))
    r = CliRunner().invoke(main, ["run", "--model", "thermal_inertial", "--data", str(bad), "--backend", "numpy"])
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert r.exit_code == 2 and len(lines) == 1, r.output
    assert lines[0].startswith("error:") and "latin1.csv:1: not UTF-8" in lines[0] and "0xb0" in lines[0]


def test_byte_order_mark_is_accepted(tmp_path):
    """Spreadsheets write UTF-8 with a byte-order mark; it must not hide the first column."""
    p = tmp_path / "bom.csv"
    p.write_bytes(GOOD.encode("utf-8-sig"))
    assert list(read_log(p))[0] == "time_s"


def test_inputs_come_from_the_models_log_columns(tmp_path):
    """A model naming its input column (log_columns) without log_arrays: that column is its input.
    Catches the loader reading u1 (a KeyError, or another column when the log has a u1 too)."""
    from types import SimpleNamespace

    from pfbench.errors import ModelError

    p = _write(tmp_path, "time_s,y,u1,heater\n0,1.0,7,0.5\n1,1.5,7,0.25\n")
    model = SimpleNamespace(n_x=1, n_y=1, n_u=1, log_columns=("heater",), name="heated")
    np.testing.assert_array_equal(load_log(p, model).u[:, 0], [0.5, 0.25])
    with pytest.raises(ModelError, match="log_columns names 2 column"):
        load_log(p, SimpleNamespace(n_x=1, n_y=1, n_u=1, log_columns=("u1", "heater"), name="heated"))


@pytest.mark.parametrize("header,needle", [("time_s,y,u1,y", r"column\(s\) y twice"),
                                           ("time_s,y,u1,", "empty column name")])
def test_a_header_with_a_repeated_or_empty_name_is_refused(tmp_path, header, needle):
    """Catches the last of two same-named columns silently winning, or an empty name reported as a
    non-numeric value."""
    p = _write(tmp_path, f"{header}\n0,1,2,3\n1,1,2,3\n")
    with pytest.raises(DataError, match=needle):
        read_log(p)
