"""Mistakes in board, system, scenario and firmware-image files that a review found accepted
(exit 0, with a motor that never turned or turned the wrong way) or reported at run time (a bus
fault, exit 1): each is now one line at the file's line, exit 2, before the run."""

import io
from contextlib import redirect_stdout
from pathlib import Path
from typing import ClassVar

import pytest

import mcusim
from mcusim.cli import main

FW = Path(__file__).resolve().parents[1] / "firmware" / "controlmotor_c"


def _edited(tmp_path, board, old, new, name="b.toml"):
    buf = io.StringIO()
    with redirect_stdout(buf):
        assert main(["boards", "--show", board]) == 0
    text = buf.getvalue()
    assert old in text, old
    p = tmp_path / name
    p.write_text(text.replace(old, new, 1))
    return str(p)


def _one_error(capsys, argv):
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("mcusim: error:"), err
    return err[0]


def _line_of(path, text):
    return next(i for i, line in enumerate(Path(path).read_text().splitlines(), 1) if text in line)


# --- board profiles ---------------------------------------------------------------------------------
def test_an_external_interrupt_on_a_pin_no_port_has_is_refused_at_its_line(tmp_path, capsys):
    path = _edited(tmp_path, "pro-mini", 'kind = "avr-extint"', 'kind = "avr-extint"\npins = ["PD9", "PD3"]')
    msg = _one_error(capsys, ["run", path, "--duration", "1ms"])
    line = _line_of(path, 'pins = ["PD9"')
    assert f"b.toml:{line}:" in msg and "no port has a pin PD9" in msg


def test_two_peripheral_outputs_on_one_pin_are_refused(tmp_path, capsys):
    path = _edited(tmp_path, "pro-mini", 'outputs = { A = "PB1", B = "PB2" }', 'outputs = { A = "PB1", B = "PB1" }')
    assert "TIMER1 output A already drives that pin" in _one_error(capsys, ["run", path, "--duration", "1ms"])
    path = _edited(tmp_path, "pro-mini", 'outputs = { A = "PB1", B = "PB2" }', 'outputs = { A = "PD6", B = "PB2" }')
    assert "TIMER0 output A already drives that pin" in _one_error(capsys, ["run", path, "--duration", "1ms"])


def test_a_part_without_a_key_it_cannot_do_without_names_the_key(tmp_path, capsys):
    path = _edited(tmp_path, "nucleo-f746", 'motor = "motor1"\n', "")
    msg = _one_error(capsys, ["run", path, "--duration", "1ms"])
    assert "part bridgeA (l6206): missing motor = ..." in msg and "b.toml:" in msg


def test_a_twi_without_bus_is_on_the_documented_default_bus_i2c0(tmp_path):
    path = _edited(tmp_path, "pro-mini", 'bus = "i2c0"', "")
    sim = mcusim.load(path)
    assert sim.mcu.periph["TWI"].bus.name == "i2c0"
    sim.close()


@pytest.mark.parametrize("board, old, new, core", [
    ("nucleo-f746", 'kind = "controlmotor"', 'kind = "openrover-mcm"', "avr"),
    ("pro-mini", 'kind = "openrover-mcm"', 'kind = "controlmotor"', "cortex-m"),
])
def test_a_firmware_for_another_core_family_is_refused_before_it_runs(tmp_path, capsys, board, old, new, core):
    path = _edited(tmp_path, board, old, new)
    assert f"runs on a core of the {core} family" in _one_error(capsys, ["run", path, "--duration", "1ms"])


def test_an_avr_peripheral_outside_the_io_space_is_refused_not_a_bus_fault_later(tmp_path, capsys):
    path = _edited(tmp_path, "pro-mini", "base = 0x29", "base = 0x10000")
    msg = _one_error(capsys, ["run", path, "--duration", "1ms"])
    portd = _line_of(path, 'name = "PORTD"')
    assert "outside the I/O space (0x20-0xff)" in msg and f"b.toml:{portd - 1}: peripheral PORTD" in msg


def test_a_default_vector_the_core_does_not_have_is_refused(tmp_path, capsys):
    path = _edited(tmp_path, "pro-mini", "vectors = 26", "vectors = 20")
    assert "ADC: vector 21 (its default) is not one of the core's 20 vectors" in _one_error(
        capsys, ["run", path, "--duration", "1ms"])
    path = _edited(tmp_path, "pro-mini", "vectors = 26", "vectors = 10")
    assert "TIMER0: vector 14 is not one of the core's 10 vectors" in _one_error(
        capsys, ["run", path, "--duration", "1ms"])


def test_an_analog_output_that_does_not_exist_is_refused_at_its_line(tmp_path, capsys):
    path = _edited(tmp_path, "pro-mini", 'A0 = "ibt2.IS_R"', 'A0 = "ibt2.NOPE"')
    assert f"b.toml:{_line_of(path, 'A0 = ')}: [analog] A0" in _one_error(capsys, ["run", path, "--duration", "1ms"])


# --- systems ----------------------------------------------------------------------------------------
def test_a_second_source_for_a_members_analog_input_is_refused(tmp_path, capsys):
    path = _edited(tmp_path, "rover-diff", '"rcm.CH1" = "vbat_divider"',
                   '"rcm.CH1" = "vbat_divider"\n"left.A0" = "vbat_divider"')
    assert "left's A0 already follows an output" in _one_error(capsys, ["run", path, "--duration", "1ms"])


def test_a_link_to_a_terminal_the_boards_own_pins_wire_is_refused(tmp_path, capsys):
    path = _edited(tmp_path, "rover-diff", '"estop.ENABLE_OUT" = ["left.ibt2.R_EN"',
                   '"estop.ENABLE_OUT" = ["left.ibt2.RPWM"')
    msg = _one_error(capsys, ["run", path, "--duration", "1ms"])
    assert "the board's own [pins] wire it to its pin PB1" in msg


@pytest.mark.parametrize("source, words", [
    ("estop.ENABLE_IN", "ENABLE_IN is not an output of estop"),
    ("estop.SENSE", "[pins] wires it to rcm.GPIO3_0 as well"),
])
def test_a_link_from_an_input_or_from_a_wired_terminal_is_refused(tmp_path, capsys, source, words):
    path = _edited(tmp_path, "rover-diff", '"estop.ENABLE_OUT" = ', f'"{source}" = ')
    assert words in _one_error(capsys, ["run", path, "--duration", "1ms"])


def test_one_module_address_for_two_wheels_is_refused(capsys):
    msg = _one_error(capsys, ["run", "elementall", "--set", "firmware.modules=8,8,9,10", "--duration", "1ms"])
    assert "address 0x08 is given twice" in msg


# --- scenarios --------------------------------------------------------------------------------------
def _scenario(tmp_path, body):
    p = tmp_path / "s.toml"
    p.write_text('[scenario]\nboard = "nucleo-f746"\nduration = "50ms"\n' + body)
    return str(p)


def test_a_follow_from_a_number_to_a_true_false_input_is_refused_at_load(tmp_path, capsys):
    sc = _scenario(tmp_path, '[[at]]\ntime = "10ms"\nfollow = { from = "/motor1/get_pos", to = "/motor2/enable" }\n')
    msg = _one_error(capsys, ["run", "nucleo-f746", "--scenario", sc, "--csv", str(tmp_path / "f.csv")])
    assert "s.toml:6:" in msg and "expected true or false" in msg
    assert not list(tmp_path.glob("f.csv*"))         # refused before the run: no partial output


def test_one_set_key_written_quoted_and_dotted_is_refused(tmp_path, capsys):
    sc = _scenario(tmp_path, '[set]\n"motor1.R" = 2.5\nmotor1.R = 3\n')
    assert "s.toml:6: [set]: motor1.R is set twice (also at line 5" in _one_error(
        capsys, ["run", "nucleo-f746", "--scenario", sc])


def test_a_follow_report_starting_after_the_end_is_refused_at_load(tmp_path, capsys):
    sc = _scenario(tmp_path, '[report]\nfollow = { leader = "motor1", follower = "motor2", from = "100ms" }\n')
    assert "from 100ms is after the end of the run" in _one_error(capsys, ["run", "nucleo-f746", "--scenario", sc])


# --- firmware images and their topic maps -----------------------------------------------------------
def _image(tmp_path, topics_edit=None, elf_edit=None):
    elf = tmp_path / "app.elf"
    raw = bytearray((FW / "controlmotor.elf").read_bytes())
    if elf_edit:
        elf_edit(raw)
    elf.write_bytes(raw)
    text = (FW / "controlmotor.topics.toml").read_text()
    (tmp_path / "app.topics.toml").write_text(topics_edit(text) if topics_edit else text)
    return str(elf)


@pytest.mark.parametrize("edit, words", [
    (lambda t: t.replace('count = "motor1_set_pos_count"', 'count = "motor1_set_pos"'), "is the topic's own symbol"),
    (lambda t: t.replace('symbol = "motor1_enable"', 'symbol = "motor1_set_pos"').replace(
        'type = "bool"', 'type = "f32"', 1), "share RAM"),
    (lambda t: t.replace('direction = "pub"', 'direction = "pub"\ncount = "motor1_set_pos_count"', 1),
     'count goes with direction = "sub"'),
])
def test_topic_map_entries_that_would_corrupt_each_other_are_refused(tmp_path, capsys, edit, words):
    elf = _image(tmp_path, topics_edit=edit)
    assert words in _one_error(capsys, ["run", "nucleo-f746", "--firmware", elf, "--duration", "1ms"])


def test_a_relocatable_object_is_refused_as_not_linked(tmp_path, capsys):
    elf = _image(tmp_path, elf_edit=lambda raw: raw.__setitem__(slice(16, 18), (1).to_bytes(2, "little")))
    assert "a relocatable object (.o), not a linked executable" in _one_error(
        capsys, ["run", "nucleo-f746", "--firmware", elf, "--duration", "1ms"])


def test_an_empty_firmware_name_is_refused_as_empty(capsys):
    assert "--firmware: an empty name" in _one_error(capsys, ["run", "nucleo-f746", "--firmware", "", "--duration", "1ms"])


def test_a_boot_address_off_the_vector_tables_alignment_is_the_profiles_mistake(tmp_path, capsys):
    path = _edited(tmp_path, "nucleo-f746", "boot_address = 0x00200000", "boot_address = 0x1")
    msg = _one_error(capsys, ["run", path, "--firmware", "controlmotor", "--duration", "1ms"])
    assert f"b.toml:{_line_of(path, 'boot_address')}: [core] boot_address = 0x1: a vector table of 114 " in msg
    # 16 + 98 entries of 4 bytes: 456, aligned to 512 (ARMv7-M, VTOR); 128 alone is not enough
    path = _edited(tmp_path, "nucleo-f746", "boot_address = 0x00200000", "boot_address = 0x00200080")
    assert "aligned to 512 bytes; the nearest are 0x200000 and 0x200200" in _one_error(
        capsys, ["run", path, "--firmware", "controlmotor", "--duration", "1ms"])


def test_the_shipped_topic_maps_still_load():
    for name in ("controlmotor", "controlmotor_thesis"):
        sim = mcusim.load("nucleo-f746", firmware=FW / f"{name}.elf")
        assert "/motor1/set_pos" in sim.firmware.topics
        sim.close()


@pytest.mark.parametrize("argv, what", [
    (["run", "/dev/zero", "--duration", "1ms"], "a board profile is a file"),
    (["run", "nucleo-f746", "--scenario", "/dev/zero"], "a scenario is a file"),
    (["run", "nucleo-f746", "--firmware", "/dev/zero", "--duration", "1ms"], "a firmware image (ELF) is a file"),
])
def test_a_device_given_as_an_input_file_is_refused_not_read_until_memory_runs_out(capsys, argv, what):
    if not Path("/dev/zero").exists():
        pytest.skip("no /dev/zero here")
    assert f"/dev/zero: not a regular file; {what}" in _one_error(capsys, argv)


def test_an_unknown_firmware_key_in_a_members_own_set_is_named_at_its_line(tmp_path, capsys):
    path = _edited(tmp_path, "rover-diff", 'set = { "firmware.layout"', 'set = { "firmware.nope" = 1, "firmware.layout"')
    msg = _one_error(capsys, ["run", path, "--duration", "1ms"])
    assert f"b.toml:{_line_of(path, 'firmware.nope')}: member rcm: set: firmware.nope: unknown firmware parameter" in msg


# --- a rover wheel's load belongs to the body -------------------------------------------------------
@pytest.mark.parametrize("key", ["mcm1.motor.load_torque=50", "mcm2.motor.load_inertia=5"])
def test_a_set_of_a_rover_wheels_load_is_refused_since_the_body_owns_it(capsys, key):
    """The rover body sets each wheel motor's load torque and inertia from the vehicle's motion
    at every step: a --set of them was overwritten before the first step, silently."""
    msg = _one_error(capsys, ["run", "elementall", "--set", key, "--duration", "1ms"])
    assert f"--set {key.split('=')[0]}: this wheel's load comes from body" in msg


def test_the_api_and_a_scenario_torque_on_a_rover_wheel_are_refused_but_a_stall_fault_works(tmp_path, capsys):
    from mcusim.errors import ConfigError
    sim = mcusim.load("elementall")
    with pytest.raises(ConfigError, match="load comes from body"):
        sim.part("mcm1.motor").apply_load_torque(40.0)
    sim.run(seconds="2ms")                   # the body goes on setting it
    assert sim.part("mcm1.motor").params.load_torque == sim.part("body").wheel_loads[0]
    sim.close()
    sc = tmp_path / "s.toml"
    sc.write_text('[scenario]\nboard = "elementall"\nduration = "20ms"\n[[at]]\ntime = "10ms"\n'
                  'torque = { motor = "mcm1.motor", nm = 40.0 }\n')
    assert "s.toml:6:" in _one_error(capsys, ["run", "elementall", "--scenario", str(sc)])
    sc.write_text('[scenario]\nboard = "elementall"\nduration = "20ms"\n[[at]]\ntime = "10ms"\n'
                  'fault = { kind = "stall", motor = "mcm1.motor" }\n')
    assert main(["run", "elementall", "--scenario", str(sc), "-q"]) == 0


def test_a_motor_is_the_wheel_of_one_body_only():
    from mcusim.errors import ConfigError
    from mcusim.plant.rover import RoverBody
    sim = mcusim.load("elementall")
    wheels = [sim.part(f"mcm{k}.motor") for k in (1, 2, 3, 4)]
    with pytest.raises(ConfigError, match="is a wheel of body already"):
        RoverBody(sim.kernel, name="body2", motors=wheels, sides="LRLR")
    sim.close()


def test_a_timer_output_on_a_pin_a_part_drives_is_refused(tmp_path, capsys):
    path = _edited(tmp_path, "pro-mini", 'outputs = { A = "PB1", B = "PB2" }', 'outputs = { A = "PD3", B = "PB2" }')
    assert "[pins] has encoder.A drive that pin" in _one_error(capsys, ["run", path, "--duration", "1ms"])


def test_a_link_target_driven_by_two_sources_is_refused(tmp_path, capsys):
    path = _edited(tmp_path, "rover-diff", '"estop.ENABLE_OUT" = [', '"estop.SENSE" = ["left.ibt2.R_EN"]\n'
                   '"estop.ENABLE_OUT" = [')
    path = Path(path)
    path.write_text(path.read_text().replace('"rcm.GPIO3_0" = "estop.SENSE"\n', ""))
    assert "is driven by estop.SENSE too" in _one_error(capsys, ["run", str(path), "--duration", "1ms"])


def test_a_rover_wheels_load_in_a_members_own_set_is_refused_at_its_line(tmp_path, capsys):
    path = _edited(tmp_path, "rover-diff", 'set = { "firmware.i2c_address" = 0x08 }',
                   'set = { "firmware.i2c_address" = 0x08, "motor.load_torque" = 5.0 }')
    msg = _one_error(capsys, ["run", path, "--duration", "1ms"])
    assert f"b.toml:{_line_of(path, 'motor.load_torque')}: member left: set: motor.load_torque" in msg


def test_two_pub_topics_on_one_symbol_are_an_alias_not_a_conflict(tmp_path):
    elf = _image(tmp_path, topics_edit=lambda t: t + '\n[topics."/pos"]\nsymbol = "motor1_get_pos"\n'
                 'type = "f32"\ndirection = "pub"\n')
    sim = mcusim.load("nucleo-f746", firmware=elf)
    sim.run(seconds="30ms")
    assert sim.topic("/pos") == sim.topic("/motor1/get_pos")
    sim.close()


def test_a_plugin_peripheral_may_make_pins_of_its_own_and_take_no_bus(tmp_path):
    """The pin check is for a port's mistyped pin (PD9); a plugin's own pin ("BUZZ") and a
    plugin's optional bus left out (None, not a bus named None) are its business."""
    from mcusim import kinds
    from mcusim.params import Param
    from mcusim.registers import Peripheral

    class Beeper(Peripheral):
        BUS_WIDTH = 1
        ACCESS_SIZES = (1,)
        PARAMS: ClassVar[dict] = {"pin": Param("BUZZ"), "bus": Param(None, kind=str)}

        def __init__(self, name, mcu, pin="BUZZ", bus=None):
            super().__init__(name)
            self.out, self.bus = mcu.add_pin(pin), bus
    kinds.register("peripheral", "test-beeper", Beeper)
    try:
        path = _edited(tmp_path, "pro-mini", '[[peripheral]]\nname = "EXINT"',
                       '[[peripheral]]\nname = "BEEP"\nkind = "test-beeper"\npin = "BUZZ"\n\n'
                       '[[peripheral]]\nname = "EXINT"')
        sim = mcusim.load(path, firmware=False)
        assert sim.mcu.periph["BEEP"].bus is None and "BUZZ" in sim.mcu.pins
        sim.close()
    finally:
        kinds._entry_points("peripheral").pop("test-beeper", None)


def test_a_timers_default_vector_beyond_the_cores_is_refused(tmp_path, capsys):
    path = _edited(tmp_path, "pro-mini", "vectors = 26", "vectors = 12")
    text = Path(path).read_text()
    for name in ("ADC", "TWI"):
        text = text.replace(f'name = "{name}"\n', f'name = "{name}"\nvector = 5\n', 1)
    Path(path).write_text(text)
    msg = _one_error(capsys, ["run", path, "--duration", "1ms"])
    assert "TIMER0: vector 14 is not one of the core's 12 vectors" in msg     # Timer0's own default


# --- found by a new user's review (session 23) ---------------------------------------------------------
def test_a_link_to_a_board_the_system_lacks_names_the_board_at_the_links_line(tmp_path, capsys):
    p = _edited(tmp_path, "elementall", '"mcm4.ibt2.L_EN"]', '"mcm9.ibt2.L_EN"]')
    err = _one_error(capsys, ["run", p, "--duration", "1ms"])
    assert f"b.toml:{_line_of(p, 'estop.ENABLE_OUT')}:" in err and "no board 'mcm9' in this system" in err, err


def test_firmware_for_another_core_family_is_named_at_its_kind_line(tmp_path, capsys):
    p = _edited(tmp_path, "nucleo-f746", 'kind = "controlmotor"', 'kind = "openrover-mcm"')
    err = _one_error(capsys, ["run", p, "--duration", "1ms"])
    assert f"b.toml:{_line_of(p, 'openrover-mcm')}:" in err and "avr family" in err, err


@pytest.mark.parametrize("key, shown", [("mcm1.motor.", "--set mcm1.motor.:"),
                                        ("mcm1.mcm2.motor.R", "--set mcm1.mcm2.motor.R:")])
def test_a_members_key_mistake_is_shown_with_the_member_as_typed(capsys, key, shown):
    """The member prefix had been stripped from the key the message showed (``--set motor.``)."""
    err = _one_error(capsys, ["run", "elementall", "--duration", "1ms", "--set", f"{key}=1"])
    assert shown in err, err


def test_a_members_own_set_may_say_present_false_as_the_command_line_does(tmp_path, capsys):
    """``set = { present = false }`` in a [[member]] had been taken as a firmware input and blamed
    on a --set the user never gave; it now leaves the board unpowered, as --set mcm1.present=false
    does, and the command line still wins."""
    old = 'set = { "firmware.i2c_address" = 0x08 }'
    p = _edited(tmp_path, "elementall", old, 'set = { "firmware.i2c_address" = 0x08, "present" = false }')
    sim = mcusim.load(p)
    try:
        assert not sim.members["mcm1"]["present"] and sim.members["mcm2"]["present"]
    finally:
        sim.discard()
    sim = mcusim.load(p, overrides={"mcm1.present": True})
    try:
        assert sim.members["mcm1"]["present"]
    finally:
        sim.discard()
    bad = _edited(tmp_path, "elementall", old, 'set = { "firmware.i2c_address" = 0x08, "present" = "maybe" }',
                  name="c.toml")
    err = _one_error(capsys, ["run", bad, "--duration", "1ms"])
    assert f"c.toml:{_line_of(bad, 'maybe')}:" in err and "expected true or false" in err, err
