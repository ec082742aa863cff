"""Bad inputs a new-user review found answered loosely; each must be one line and exit 2 (or say
when a run-time fault happened), per the rule that bad input never gives a traceback or a silent
wrong result."""

import os
import signal
import subprocess
import sys

import pytest

from mcusim.board import parse_value
from mcusim.cli import main


def _profile(tmp_path, edit):
    import io
    from contextlib import redirect_stdout
    buf = io.StringIO()
    with redirect_stdout(buf):
        assert main(["boards", "--show", "nucleo-f746"]) == 0
    p = tmp_path / "b.toml"
    p.write_text(edit(buf.getvalue()))
    return str(p)


def _one_error(capsys, argv, code=2):
    assert main(argv) == code
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("mcusim: error:"), err
    return err[0]


def test_a_bare_number_is_refused_as_a_board_frequency(tmp_path, capsys):
    path = _profile(tmp_path, lambda s: s.replace('sysclk = "216MHz"', "sysclk = 216000000"))
    assert "unit" in _one_error(capsys, ["run", path, "--duration", "1ms"])


def test_two_gpio_ports_with_one_letter_are_refused(tmp_path, capsys):
    path = _profile(tmp_path, lambda s: s.replace('port = "I"', 'port = "A"'))
    assert "port A is declared twice" in _one_error(capsys, ["run", path, "--duration", "1ms"])


def test_a_deeply_nested_toml_file_is_a_usage_error(tmp_path, capsys):
    p = tmp_path / "deep.toml"
    p.write_text("[board]\nx = " + "[" * 3000 + "]" * 3000 + "\n")
    assert "nested too deeply" in _one_error(capsys, ["run", str(p), "--duration", "1ms"])


def test_a_peripheral_the_firmware_needs_is_named_when_missing(tmp_path, capsys):
    def drop_tim1(s):
        i = s.index('name = "TIM1"')
        j, k = s.rfind("[[peripheral]]", 0, i), s.index("[[peripheral]]", i)
        return s[:j] + s[k:]
    msg = _one_error(capsys, ["run", _profile(tmp_path, drop_tim1), "--duration", "1ms"])
    assert "needs 'TIM1'" in msg and "does not declare" in msg


@pytest.mark.parametrize("opt", ["--vcd", "--csv", "--summary"])
def test_standard_output_is_for_the_register_log_only(tmp_path, capsys, opt):
    assert "standard output" in _one_error(capsys, ["run", "nucleo-f746", "--duration", "1ms", opt, "-"])


def test_a_vcd_to_a_device_writes_no_layout_file_beside_it(tmp_path, capsys):
    if not os.path.exists("/dev/null"):
        pytest.skip("no /dev/null")
    assert main(["run", "nucleo-f746", "--duration", "1ms", "--vcd", "/dev/null", "--quiet"]) == 0
    assert not os.path.exists("/dev/null.gtkw")


def test_a_register_filter_naming_a_missing_register_is_refused(capsys):
    msg = _one_error(capsys, ["trace", "nucleo-f746", "--duration", "1ms", "--filter", "TIM1.CCR9"])
    assert "TIM1 has no register CCR9" in msg


def test_an_empty_trace_filter_is_refused_under_its_own_name(capsys):
    msg = _one_error(capsys, ["trace", "nucleo-f746", "--duration", "1ms", "--filter", " , "])
    assert msg.startswith("mcusim: error: --filter is empty"), msg


def test_set_values_take_lists_and_hex_integers():
    assert parse_value("8,9") == [8, 9] and parse_value("[8, 9]") == [8, 9]
    assert parse_value("0x08") == 8 and parse_value("0b101") == 5
    assert parse_value("[]") == [] and parse_value("[ 8 ]") == [8]


@pytest.mark.parametrize("value", ["8,,9,10,11", "8,9,10,11,", ",8,9", "[8,,9]", "[8,9,]"])
def test_a_list_with_an_empty_item_is_refused_naming_its_key(capsys, value):
    """A doubled or stray comma is a typo, not a shorter list (it was dropped silently)."""
    msg = _one_error(capsys, ["run", "ciaa-edu", "--duration", "1ms", "-q", "--set", f"firmware.modules={value}"])
    assert msg.startswith(f"mcusim: error: firmware.modules = {value!r}: an empty item in a list"), msg


def test_a_fault_found_during_the_run_says_when(capsys):
    msg = _one_error(capsys, ["run", "nucleo-f746", "--duration", "20ms", "--quiet", "--set", "bridgeA.I_ocd=2",
                              "--set", "bridgeA.drive_en=true", "--set", "/motor1/set_pos=3"], code=1)
    assert "contention" in msg and "at simulated t = " in msg


def test_sigterm_leaves_partial_outputs_marked_and_exits_143(tmp_path):
    p = subprocess.Popen([sys.executable, "-m", "mcusim", "run", "nucleo-f746", "--duration", "60s", "--quiet",
                          "--vcd", str(tmp_path / "t.vcd")], stderr=subprocess.PIPE, text=True, cwd=tmp_path)
    import time
    deadline = time.time() + 60
    part = tmp_path / "t.vcd.part"
    # the .part exists (empty) from the output check on; wait until the run has written to it (a
    # loaded machine may still be building the simulation half a second later)
    while not (part.exists() and part.stat().st_size > 0) and time.time() < deadline:
        time.sleep(0.1)
    time.sleep(0.5)
    p.send_signal(signal.SIGTERM)
    _, err = p.communicate(timeout=60)
    assert p.returncode == 143 and "terminated" in err and "t.vcd.part" in err
    assert not [f for f in os.listdir(tmp_path) if f.endswith(".tmp.gtkw")]


def test_two_modules_on_one_i2c_address_are_refused_before_the_run(capsys):
    """A firmware parameter declared unique (a bus address) differs between a system's boards;
    before, two slaves on 0x09 were found only mid-run (exit 1), or never in a short run."""
    msg = _one_error(capsys, ["run", "elementall", "--duration", "1ms", "--set", "mcm1.firmware.i2c_address=9"])
    assert "mcm1 and mcm2 both have firmware.i2c_address = 0x09" in msg


@pytest.mark.parametrize("key,value", [("mcm2.motor.R", "0"), ("mcm1.firmware.kp", "-1"), ("mcm1.velocity", "nan")])
def test_a_system_members_key_is_named_as_the_user_wrote_it(capsys, key, value):
    msg = _one_error(capsys, ["run", "elementall", "--duration", "1ms", "--set", f"{key}={value}"])
    assert msg.startswith(f"mcusim: error: {key} = {value}")


def test_a_misspelt_part_in_pins_is_named(tmp_path, capsys):
    path = _profile(tmp_path, lambda s: s.replace('PE9 = "bridgeA.IN1"', 'PE9 = "bridgeZ.IN1"'))
    assert "names part 'bridgeZ', which is not declared" in _one_error(capsys, ["run", path, "--duration", "1ms"])


@pytest.mark.parametrize("opt", ["--sample", "--vcd-sample"])
def test_a_sampling_grid_without_its_output_is_refused(capsys, opt):
    assert opt in _one_error(capsys, ["run", "nucleo-f746", "--duration", "1ms", opt, "1ms"])


def test_a_warning_during_the_run_is_printed_once(capsys):
    """The ADC clock warning appears once on stderr when it happens, not again after the summary
    (the JSON summary still lists it under "warnings")."""
    assert main(["run", "ciaa-edu", "--set", "firmware.adc_clkdiv=10", "--duration", "20ms"]) in (0, 1)
    out = capsys.readouterr()
    assert (out.out + out.err).count("ADC clock") == 1


def test_a_negative_duration_after_a_space_is_refused_for_what_it_is(capsys):
    """argparse takes "-1s" for an option; the user must hear that a duration cannot be negative,
    whether written --duration=-1s or --duration -1s."""
    for argv in (["--duration", "-1s"], ["--duration=-1s"]):
        assert main(["run", "nucleo-f746", *argv]) == 2
        assert "must not be negative" in capsys.readouterr().err
