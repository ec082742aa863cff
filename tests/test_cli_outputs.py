"""The command line's outputs and scripts: --scenario, --csv, --plot, --register-log, `mcusim trace`,
the GTKWave layout, and the messages and exit codes of bad input."""

import json
import textwrap

import pytest

from mcusim.cli import main

SCENARIO = """
[scenario]
board = "nucleo-f746"
duration = "30ms"

[[at]]
time = "1ms"
publish = { "/motor1/set_pos" = 0.2 }

[[expect]]
name = "moving"
time = "30ms"
part = "motor1"
attr = "output_angle"
min = {min}
"""


def _scenario(tmp_path, minimum):
    p = tmp_path / "s.toml"
    p.write_text(textwrap.dedent(SCENARIO).replace("{min}", str(minimum)))
    return str(p)


def test_scenario_passing_exits_0_and_failing_exits_1_with_the_results(tmp_path, capsys):
    assert main(["run", "nucleo-f746", "--scenario", _scenario(tmp_path, 0.001), "-q"]) == 0
    out = capsys.readouterr().out
    assert "PASS  moving" in out and "simulated 0.030000 s" in out
    assert main(["run", "nucleo-f746", "--scenario", _scenario(tmp_path, 5.0), "-q"]) == 1
    captured = capsys.readouterr()
    assert "FAIL  moving" in captured.out and "a scenario expectation failed" in captured.err


@pytest.mark.parametrize("text, where", [
    ('[scenario]\nduration = "30ms"\n[[at]]\ntime = "2ms"\nfoo = 1\n', "s.toml:5"),          # unknown key
    ('[scenario]\nduration = "30qs"\n', "s.toml:2"),                                           # bad unit
    (('[scenario]\nduration = "30ms"\n[[at]]\ntime = "5ms"\npublish = { "/motor1/set_pos" = 1 }\n'
     '[[at]]\ntime = "2ms"\npublish = { "/motor1/set_pos" = 1 }\n'), "s.toml:7"),               # out of order
    ('[scenario\nduration = "30ms"\n', "s.toml"),                                              # malformed
])
def test_a_scenario_mistake_is_one_line_naming_file_and_line_with_exit_2(tmp_path, capsys, text, where):
    p = tmp_path / "s.toml"
    p.write_text(text)
    assert main(["run", "nucleo-f746", "--scenario", str(p)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and where in err, err


def test_missing_board_and_bad_unit_are_usage_errors(capsys):
    assert main(["run", "no-such-board", "--duration", "1ms"]) == 2
    assert "unknown board 'no-such-board'" in capsys.readouterr().err
    assert main(["run", "nucleo-f746", "--sample", "1 parsec"]) == 2


def test_csv_has_units_in_the_header_and_rows_on_the_grid(tmp_path, capsys):
    csv = tmp_path / "run.csv"
    assert main(["run", "nucleo-f746", "--duration", "10ms", "--set", "/motor1/set_pos=0.1",
                 "--csv", str(csv), "--sample", "2ms", "-q"]) == 0
    lines = csv.read_text().splitlines()
    header = lines[0].split(",")
    assert header[0] == "time_s" and "motor1.angle_rad" in header and "motor1.current_a" in header
    assert [row.split(",")[0] for row in lines[1:]] == ["0", "0.002", "0.004", "0.006", "0.008", "0.01"]


@pytest.mark.parametrize("sample, times", [
    ("3ms", ["0", "0.003", "0.006", "0.009", "0.01"]),
    ("1s", ["0", "0.01"]),
])
def test_a_run_ending_between_grid_points_gets_a_last_row_at_its_end(tmp_path, capsys, sample, times):
    """Was a file ending at 0.009 s (or at 0 for a sample longer than the run), silently: the end
    state of the run was missing."""
    csv = tmp_path / "run.csv"
    assert main(["run", "nucleo-f746", "--duration", "10ms", "--set", "/motor1/set_pos=0.1",
                 "--csv", str(csv), "--sample", sample, "-q"]) == 0
    lines = csv.read_text().splitlines()
    assert [row.split(",")[0] for row in lines[1:]] == times


def test_plot_writes_a_png(tmp_path, capsys):
    png = tmp_path / "run.png"
    assert main(["run", "pro-mini", "--duration", "50ms", "--plot", str(png), "-q"]) == 0
    data = png.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 10_000


def test_vcd_comes_with_a_gtkwave_layout(tmp_path, capsys):
    vcd = tmp_path / "run.vcd"
    assert main(["run", "nucleo-f746", "--duration", "2ms", "--vcd", str(vcd), "-q"]) == 0
    gtkw = (tmp_path / "run.gtkw").read_text()
    # the dump file is named relative to the layout, so that the pair can be moved together
    assert '[dumpfile] "run.vcd"' in gtkw and "nucleo-f746.PE9" in gtkw and str(tmp_path) not in gtkw
    assert "GTKWave layout" in capsys.readouterr().out


def test_register_log_writes_json_lines_filtered_by_peripheral(tmp_path, capsys):
    log = tmp_path / "regs.jsonl"
    assert main(["run", "nucleo-f746", "--duration", "1ms", "--register-log", str(log),
                 "--register-log-filter", "TIM2", "-q"]) == 0
    recs = [json.loads(line) for line in log.read_text().splitlines()]
    assert recs and all(r["reg"].startswith("TIM2.") for r in recs)
    # the thesis's bridge B timer: ARR written at start-up from the real 108 MHz clock (50 kHz)
    arr = [r for r in recs if r["reg"] == "TIM2.ARR" and r["op"] == "write"]
    assert arr[0]["addr"] == "0x4000002c" and arr[0]["changed"] == {"ARR": [0, 2159]}


def test_trace_prints_the_register_log_on_stdout_and_the_summary_on_stderr(capsys):
    assert main(["trace", "nucleo-f746", "--duration", "10us", "--filter", "TIM1.CR1"]) == 0
    captured = capsys.readouterr()
    recs = [json.loads(line) for line in captured.out.splitlines()]
    assert [r["op"] for r in recs][:2] == ["read", "write"] and {r["reg"] for r in recs} == {"TIM1.CR1"}
    cen = [r for r in recs if "CEN" in r.get("changed", {})]
    assert cen and cen[0]["changed"]["CEN"] == [0, 1]
    assert "simulated" in captured.err


def test_duration_on_the_command_line_moves_the_scenarios_end_of_run_checks(tmp_path, capsys):
    p = tmp_path / "end.toml"
    p.write_text('[scenario]\nduration = "30ms"\n[[expect]]\nname = "end"\npart = "motor1"\n'
                 'attr = "output_angle"\nmax = 1.0\n')
    assert main(["run", "nucleo-f746", "--scenario", str(p), "--duration", "10ms", "-q"]) == 0
    out = capsys.readouterr().out
    assert "simulated 0.010000 s" in out and "PASS  end" in out and "at 0.01 s" in out


@pytest.mark.parametrize("args, msg", [
    (["--set", "firmware.kp=abc"], "firmware.kp = 'abc': expected a number"),
    (["--set", "/motor1/enable=3.5"], "/motor1/enable = 3.5: expected true or false"),
    (["--set", "/motor1/set_pos=abc"], "/motor1/set_pos = 'abc': expected a number"),
    (["--csv", "/no/such/folder/x.csv"], "no folder /no/such/folder"),
    (["--summary", "/no/such/folder/s.json"], "no folder /no/such/folder"),
    (["--plot", "x.gif"], "must end in .png"),
    (["--register-log", "r.jsonl", "--register-log-filter", "TIM33"], "'TIM33' matches no peripheral"),
])
def test_bad_values_and_outputs_are_usage_errors_found_before_the_run(tmp_path, capsys, monkeypatch, args, msg):
    monkeypatch.chdir(tmp_path)
    assert main(["run", "nucleo-f746", "--duration", "1ms", *args]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and msg in err, err


def test_scenario_values_are_checked_against_the_topic_type_with_file_and_line(tmp_path, capsys):
    for body, msg in (('[[at]]\ntime = "1ms"\npublish = { "/motor1/set_pos" = "abc" }\n', "s.toml:5: "),
                      ('[[at]]\ntime = nan\npublish = { "/motor1/set_pos" = 1.0 }\n', "s.toml:4: ")):
        p = tmp_path / "s.toml"
        p.write_text('[scenario]\nduration = "5ms"\n' + body)
        assert main(["run", "nucleo-f746", "--scenario", str(p)]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and msg in err, err


def test_bench_repeat_must_be_positive(capsys):
    assert main(["bench", "nucleo-f746", "--repeat", "0"]) == 2
    assert "argument --repeat: 0: must be from 1 to 100" in capsys.readouterr().err


def test_avr_interrupt_lines_are_in_the_vcd_and_the_module_command_comes_after_the_boot(tmp_path, capsys):
    """The host's command waits for the module to boot: the PJRC Encoder's constructor waits 2 ms
    for its pull-ups before main() (so init() starts the TWI after that); the host writes at 5 ms
    and is acknowledged."""
    import mcusim
    vcd = tmp_path / "pm.vcd"
    sim = mcusim.load("pro-mini", overrides={"velocity": 10})
    sim.trace_vcd(str(vcd))
    master = sim.firmware._host()
    sim.run(seconds="7ms")
    sim.close()
    text = vcd.read_text()
    for name in ("EXINT_INT0", "TIMER1_OVF", "TIMER0_OVF", "TWI", "ADC"):
        assert f" {name} $end" in text
    (tr,) = master.transfers
    assert tr.t_start == sim.timebase.ticks("5ms") and tr.ok


def test_bench_engine_both_reports_both_factors_and_their_ratio(tmp_path, capsys):
    """Issue: `bench --engine both` runs the two engines in one process; --json has
    realtime_factor (fast), reference_realtime_factor and speedup = their ratio."""
    import json

    from mcusim.cli import main
    out = tmp_path / "b.json"
    assert main(["bench", "nucleo-f746", "--engine", "both", "--repeat", "1", "--duration", "5ms",
                 "--json", str(out)]) == 0
    r = json.loads(out.read_text())
    assert r["engine"] == "both" and r["reference_realtime_factor"] > 0 and r["realtime_factor"] > 0
    assert abs(r["speedup"] - r["realtime_factor"] / r["reference_realtime_factor"]) < 1e-12
    assert "speedup" in capsys.readouterr().out


def test_a_register_log_whose_filter_matched_no_access_says_so(tmp_path, capsys):
    """TIM3 is an encoder timer on the nucleo-f746: its CCR1 is never accessed, and an empty log
    with exit 0 looked like a broken option. The filter is valid (a misspelt one is refused)."""
    log = tmp_path / "r.jsonl"
    assert main(["run", "nucleo-f746", "--duration", "5ms", "-q", "--register-log", str(log),
                 "--register-log-filter", "TIM3.CCR1"]) == 0
    assert "no access: the filter TIM3.CCR1 names registers this run never touched" in capsys.readouterr().out
    assert log.read_text() == ""
    assert main(["run", "nucleo-f746", "--duration", "5ms", "-q", "--register-log", str(log),
                 "--register-log-filter", "TIM1.CCR1"]) == 0
    assert "no access" not in capsys.readouterr().out and log.read_text()
