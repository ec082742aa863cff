"""Board profiles are data (issue 11): kinds from a registry, never an import named by the file;
the schema of docs/boards.md checked with file:line errors; the walk-through of docs/boards.md."""

import importlib.metadata
import json
import re
import sys
from pathlib import Path
from typing import ClassVar

import pytest

import mcusim
from mcusim import kinds
from mcusim.board import board_names, shipped_text
from mcusim.cli import main
from mcusim.errors import ConfigError
from mcusim.params import Param

DOC = Path(__file__).resolve().parent.parent / "docs" / "boards.md"


def _err(capsys, argv):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    return err


def _edited_run_error(tmp_path, capsys, board, old, new, name):
    """(error line, line number of ``old``) of a run of ``board``'s profile with ``old`` replaced
    by ``new``, written as ``name``."""
    text = shipped_text(board)
    assert old in text
    p = tmp_path / name
    p.write_text(text.replace(old, new, 1))
    return _err(capsys, ["run", str(p), "--duration", "1ms"]), text[:text.index(old)].count("\n") + 1


def test_the_kind_tables_of_the_doc_are_the_registry():
    text = DOC.read_text()
    body = text.split("<!-- kinds:begin -->\n", 1)[1].split("<!-- kinds:end -->", 1)[0]
    expected = "".join(f"### {title}\n\n{kinds.reference(g)}\n" for g, title in
                       (("peripheral", "Peripheral kinds"), ("part", "Part kinds"), ("firmware", "Firmware kinds")))
    assert body == expected, "docs/boards.md: paste the output of `mcusim boards --kinds` between the markers"


def test_every_key_the_shipped_profiles_use_is_documented():
    import tomllib
    text = DOC.read_text()
    for name in board_names():
        prof = tomllib.loads(shipped_text(name))
        for table, value in prof.items():
            assert f"`[{table}" in text or f"`[[{table}]]`" in text, (name, table)
            if table in ("run", "bench", "pins", "analog", "pull", "links"):
                continue                   # their keys are names (pins, nets, --set keys), not schema
            for entry in value if isinstance(value, list) else [value]:
                for key in entry:
                    assert f"`{key}`" in text, (name, table, key)


def test_a_profile_cannot_name_a_python_object_to_import(tmp_path, capsys):
    marker = tmp_path / "pwned"
    evil = tmp_path / "evil.py"
    evil.write_text(f"open({str(marker)!r}, 'w').close()\nclass Tim: pass\n")
    sys.path.insert(0, str(tmp_path))
    try:
        text = shipped_text("nucleo-f746")
        for old, new in (('kind = "stm32-tim"', 'class = "evil:Tim"'),
                         ('kind = "stm32-tim"', 'kind = "evil:Tim"'),
                         ('kind = "controlmotor"', 'class = "evil:Tim"'),
                         ('kind = "dcmotor"', 'kind = "evil:Tim"')):
            p = tmp_path / "b.toml"
            p.write_text(text.replace(old, new, 1))
            err = _err(capsys, ["run", str(p), "--duration", "1ms"])
            assert re.search(r"b\.toml:\d+: ", err) and ("never a Python class" in err or "unknown" in err), err
        assert not marker.exists() and "evil" not in sys.modules
    finally:
        sys.path.remove(str(tmp_path))


@pytest.mark.parametrize("old, new, needle", [
    ('nvic_irqs = 98', 'nvic_irqs = "many"', "[core] nvic_irqs = 'many': expected an integer"),
    ('sysclk = "216MHz"', 'sysclk = "0Hz"', "[clocks] sysclk: bad frequency"),
    ('sysclk = "216MHz"', 'sysclk = "216"', "sysclk = '216': a frequency with a unit"),   # not 216 Hz
    ('sysclk = "216MHz"', 'sysclk = 216', "sysclk = 216: a frequency with a unit"),
    ('motor = "motor1"', 'motor = "motor7"', "part bridgeA: no part 'motor7' declared before it"),
    ('PE9 = "bridgeA.IN1"', 'PE9 = "bridgeX.IN1"', "[pins] names part 'bridgeX', which is not declared"),
    ('PE9 = "bridgeA.IN1"', 'PE9 = "bridgeA.Q"', "part bridgeA (l6206) has no terminal Q"),
    ('"/motor1/set_pos" = 1.57', '"/motor1/set_pos" = "abc"', "[run.set] /motor1/set_pos = 'abc': expected a number"),
    ('"/motor1/set_pos" = 1.57', '"/motor9/set_pos" = 1.57', "[run.set] no subscribed topic '/motor9/set_pos'"),
    ('counter_bits = 32', 'counter_bits = 24', "counter_bits = 24: expected one of 16, 32"),
    ('irqs = { update = 29, cc = 29 }', 'irqs = { update = 999, cc = 29 }', "update = 999: must be from 0 to 495"),
    ('irqs = { update = 29, cc = 29 }', 'irqs = { update = 120, cc = 29 }', "interrupt 120 is not one of the core's 98"),
    ('port = "E"', 'port = "Z"', "port = 'Z': expected one of A, B"),
    ('counts_per_rev = 64', 'counts_per_rev = -1', "counts_per_rev = -1: must be from 1 to 100000"),
    ('name = "motor1"\nkind = "dcmotor"', 'name = "motor1"\nkind = "dcmotor"\nR = inf',
     "R = inf: expected a finite number"),
    ('[run.set]', '[run.sett]', "[run]: unknown key 'sett' (known: set)"),
    ('[run.set]', '[runn.set]', "unknown table or key 'runn'"),
    ('name = "TIM8"', 'name = "TIM1"', "a second peripheral of that name"),
    ('base = 0x40000000', 'base = 0x40010000', "overlaps another peripheral"),
    ('PE9 = "bridgeA.IN1"', 'PE99 = "bridgeA.IN1"', "has no pin 'PE99'"),
    ('PE9 = "bridgeA.IN1"', 'PE9 = "bridgeA"', 'expected "<part>.<TERMINAL>"'),
    ('kind = "controlmotor"', 'kind = "controlmotor"\npid_period_ms = 0', "firmware.pid_period_ms = 0"),
    ('kind = "controlmotor"', 'kind = "controlmotor"\nbogus = 1', "unknown parameter 'bogus' of controlmotor"),
])
def test_profile_mistakes_name_the_file_and_line(tmp_path, capsys, old, new, needle):
    text = shipped_text("nucleo-f746")
    assert old in text
    p = tmp_path / "b.toml"
    p.write_text(text.replace(old, new, 1))
    err = _err(capsys, ["run", str(p), "--duration", "1ms"])
    assert needle in err, err
    if "overlaps" not in needle:
        line = text[:text.index(old)].count("\n") + new.count("\n") + 1     # the changed line
        assert f"b.toml:{line}: " in err, (line, err)


def test_a_bad_bench_command_names_the_board_files_line(tmp_path, capsys):
    text = shipped_text("pro-mini")
    old = "[bench.set]\nvelocity = 20"
    assert old in text
    p = tmp_path / "b.toml"
    p.write_text(text.replace(old, '[bench.set]\nvelocity = "fast"', 1))
    err = _err(capsys, ["bench", str(p), "--duration", "10ms", "--repeat", "1"])
    line = text[:text.index(old)].count("\n") + 2
    assert f"b.toml:{line}: " in err and "velocity = 'fast': expected a number" in err, err


def test_every_shipped_profile_passes_the_schema_and_builds():
    for name in board_names():
        sim = mcusim.load(name)
        sim.discard()


class _Flywheel:
    """A flywheel that is no motor (a registered part kind for the test)."""

    PARAMS: ClassVar[dict] = {"mass": Param(1.0, above=0, max=100.0, unit="kg")}
    REFS = ("motor",)

    def __init__(self, kernel, name, motor, mass=1.0):
        self.name, self.motor, self.mass = name, motor, mass


def test_a_registered_kind_is_usable_with_its_declared_parameters(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(kinds, "_registered", {})
    kinds.register("part", "flywheel", _Flywheel)
    text = shipped_text("nucleo-f746") + '\n[[part]]\nname = "wheel"\nkind = "flywheel"\nmotor = "motor1"\nmass = 2.5\n'
    p = tmp_path / "b.toml"
    p.write_text(text)
    sim = mcusim.load(str(p), overrides={"wheel.mass": 3.0})
    assert sim.part("wheel").mass == 3.0 and sim.part("wheel").motor is sim.part("motor1")
    sim.discard()
    err = _err(capsys, ["run", str(p), "--duration", "1ms", "--set", "wheel.mass=1e9"])
    assert "wheel.mass = 1e+09: must be above 0 and at most 100 kg" in err
    with pytest.raises(ConfigError, match="cannot be replaced"):
        kinds.register("part", "dcmotor", _Flywheel)


def test_an_entry_point_registers_a_kind_and_a_broken_one_is_one_line(tmp_path, capsys, monkeypatch):
    eps = [importlib.metadata.EntryPoint("flywheel", f"{__name__}:_Flywheel", "mcusim.parts"),
           importlib.metadata.EntryPoint("broken", "no_such_module_xyz:Thing", "mcusim.parts")]
    monkeypatch.setattr(kinds, "_registered", {})
    monkeypatch.setattr(importlib.metadata, "entry_points", lambda group: [e for e in eps if e.group == group])
    assert "flywheel" in kinds.known("part") and "broken" in kinds.known("part")
    base = shipped_text("nucleo-f746") + '\n[[part]]\nname = "wheel"\nmotor = "motor1"\n'
    p = tmp_path / "b.toml"
    p.write_text(base + 'kind = "flywheel"\n')
    assert main(["run", str(p), "--duration", "1ms", "-q"]) == 0
    p.write_text(base + 'kind = "broken"\n')
    err = _err(capsys, ["run", str(p), "--duration", "1ms"])
    assert "part kind 'broken' (entry point no_such_module_xyz:Thing) cannot be loaded: ModuleNotFoundError" in err


def test_the_walk_through_of_the_doc(tmp_path, capsys, monkeypatch):
    """docs/boards.md, "a board of your own": the same commands and edits, run."""
    doc = DOC.read_text()
    edits = [('name = "nucleo-f746"', 'name = "my-board"'),
             ("counts_per_rev = 64", "counts_per_rev = 48"),
             ('kind = "controlmotor"', 'kind = "controlmotor"\ncounts_per_turn = 1440'),
             ('name = "motor1"\nkind = "dcmotor"', 'name = "motor1"\nkind = "dcmotor"\nload_inertia = 2e-5')]
    for _, new in edits:
        block = "\n".join("   " + ln for ln in new.splitlines())
        assert f"   ```toml\n{block}\n   ```" in doc, new
    assert "mcusim boards --show nucleo-f746 > my-board.toml" in doc
    assert "mcusim run my-board.toml --duration 100ms --summary my-board.json" in doc
    monkeypatch.chdir(tmp_path)
    assert main(["boards", "--show", "nucleo-f746"]) == 0
    text = capsys.readouterr().out
    for old, new in edits:
        assert old in text
        text = text.replace(old, new)
    Path("my-board.toml").write_text(text)
    # the doc's 100 ms, shortened with the documented --duration (a later option wins)
    assert main(["run", "my-board.toml", "--duration", "100ms", "--summary", "my-board.json",
                 "--duration", "5ms", "-q"]) == 0
    s = json.loads(Path("my-board.json").read_text())
    assert s["board"] == "my-board" and s["simulated_s"] == 0.005
    sim = mcusim.load("my-board.toml", firmware=False)
    assert sim.part("encoder1").counts_per_rev == 48 and sim.part("motor1").params.load_inertia == 2e-5
    sim.discard()


def test_a_registered_firmware_that_is_no_firmware_is_one_line(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(kinds, "_registered", {})
    kinds.register("firmware", "not-a-firmware", _Flywheel)         # takes (kernel, name, motor)
    kinds.register("firmware", "silent", type("Silent", (), {"__init__": lambda self, mcu: None}))
    p = tmp_path / "b.toml"
    for kind, needle in (("not-a-firmware", "firmware not-a-firmware:"), ("silent", "is not a firmware")):
        p.write_text(shipped_text("nucleo-f746").replace('kind = "controlmotor"', f'kind = "{kind}"'))
        err = _err(capsys, ["run", str(p), "--duration", "1ms", "--set", "motor1.R=2"])
        assert needle in err, err


def test_a_reference_to_a_part_of_the_wrong_kind_names_the_line_and_the_kind(tmp_path, capsys):
    """Was "'L6206Bridge' object has no attribute 'angle'" without a line: an encoder's motor
    named a bridge. Each kind's references say which kinds they take."""
    text = shipped_text("nucleo-f746")
    at = text.index('name = "encoder1"')
    old = 'motor = "motor1"'
    j = text.index(old, at)
    p = tmp_path / "b.toml"
    p.write_text(text[:j] + 'motor = "bridgeA"' + text[j + len(old):])
    err = _err(capsys, ["run", str(p), "--duration", "1ms"])
    line = text[:j].count("\n") + 1
    assert f"b.toml:{line}: part encoder1: motor = 'bridgeA' is not a dcmotor part" in err, err


@pytest.mark.parametrize("old, new, needle", [
    ('loads = ["mcm1.ibt2"', 'loads = ["mcm1.motor"', "part battery: loads = 'mcm1.motor' is not a bts7960 part"),
    ('motors = ["mcm1.motor"', 'motors = ["mcm1.ibt2"', "part body: motors = 'mcm1.ibt2' is not a dcmotor part"),
    ('board = "pro-mini"', 'board = "pro-mini2"', "[[member]] mcm1: unknown board 'pro-mini2'"),
    # was blamed on boards/pro-mini.toml:90, a file the user did not touch
    ('"mcm1.ibt2.R_EN"', '"mcm1.ibt2.R_ENN"',
     "[links] estop.ENABLE_OUT: 'mcm1.ibt2.R_ENN': part ibt2 (bts7960) has no terminal R_ENN"),
    ('"mcm1.ibt2.R_EN"', '"mcm1.ibt3.R_EN"', "[links] estop.ENABLE_OUT: 'mcm1.ibt3.R_EN': the board has no part 'ibt3'"),
    # were the lines of unrelated [[part]] tables
    ('"estop.ENABLE_IN"', '"estopp.ENABLE_IN"', "[pins] names part 'estopp', which is not declared"),
    ('"estop.SENSE"', '"estop.SENSEX"', "part estop (estop) has no terminal SENSEX"),
    # was "[pins] names part 'nope'" at the line of the [[part]] battery table
    ('"estop.ENABLE_OUT" =', '"nope.ENABLE_OUT" =', "[links] 'nope.ENABLE_OUT' names part 'nope', which is not declared"),
    # these had no line
    ('main = "rcm"', 'main = "nope"', "[system] main = 'nope' is not a member (rcm, mcm1, mcm2, mcm3, mcm4)"),
    ('"rcm.GPIO3_3" =', '"xx.GPIO3_3" =', "[pins] 'xx.GPIO3_3': no member 'xx' (members: rcm, mcm1"),
    ('board = "pro-mini"', 'board = "elementall"', "member mcm1: elementall is a system, not a board"),
])
def test_a_system_parts_reference_of_the_wrong_kind_names_the_line(tmp_path, capsys, old, new, needle):
    """Were "load 'motor' is not a bridge", "'ibt2' is not a wheel motor" and "unknown board" without
    file:line."""
    err, line = _edited_run_error(tmp_path, capsys, "elementall", old, new, "s.toml")
    assert f"s.toml:{line}: {needle}" in err, err


def test_two_modules_on_one_bus_address_are_named_at_the_second_ones_table(tmp_path, capsys):
    """Had no line: the mistake is in the member whose address repeats an earlier one's."""
    text = shipped_text("elementall")
    p = tmp_path / "s.toml"
    p.write_text(text.replace('"firmware.i2c_address" = 0x09', '"firmware.i2c_address" = 0x08', 1))
    err = _err(capsys, ["run", str(p), "--duration", "1ms"])
    table = text[:text.index('name = "mcm2"')].count("\n")      # the [[member]] line above it
    assert f"s.toml:{table}: mcm1 and mcm2 both have firmware.i2c_address = 0x08" in err, err


def test_a_usart_without_its_interrupt_line_names_the_table_and_the_lines_it_may_take(tmp_path, capsys):
    """Was "Usart.__init__() missing 1 required positional argument: 'irq'" without a line; the
    documented "default 0" of every interrupt number was not what a missing one did (the ADC
    and the TWI take the chip's own line, the USART none)."""
    text = shipped_text("ciaa-edu")
    at = text.index('kind = "lpc43xx-usart"')
    j = text.index("irq = ", at)
    p = tmp_path / "c.toml"
    p.write_text(text[:j] + text[text.index("\n", j) + 1:])
    err = _err(capsys, ["run", str(p), "--duration", "1ms"])
    assert "lpc43xx-usart needs irq = ... (NVIC interrupt line: 24 USART0" in err and "c.toml:" in err, err
    from mcusim import kinds
    ref = kinds.reference("peripheral")
    assert "default 0" not in "\n".join(line for line in ref.splitlines() if line.startswith(("| `irq`", "| `vector`")))


def test_a_reference_to_a_part_declared_later_says_so(tmp_path, capsys):
    """Was "no part 'encoder1' declared before it" for a part that is declared, later."""
    text = shipped_text("nucleo-f746")
    old = 'motor = "motor1"'
    p = tmp_path / "b.toml"
    # bridgeA names encoder1 (declared after it, and not a motor): the kind is the first problem
    p.write_text(text.replace(old, 'motor = "encoder1"', 1))
    err = _err(capsys, ["run", str(p), "--duration", "1ms"])
    assert "part bridgeA: motor = 'encoder1' is not a dcmotor part" in err, err


def test_an_unwired_terminal_names_the_parts_line(tmp_path, capsys):
    text = shipped_text("nucleo-f746")
    p = tmp_path / "b.toml"
    start = text.index('PE9 = "bridgeA.IN1"')
    text = text[:start] + text[text.index("\n", start) + 1:]
    p.write_text(text)
    err = _err(capsys, ["run", str(p), "--duration", "1ms"])
    line = text[:text.rindex("[[part]]", 0, text.index('name = "bridgeA"'))].count("\n") + 1   # its table
    assert f"b.toml:{line}: part bridgeA: terminal IN1 is not wired in [pins]" in err, err


def test_a_run_set_key_of_the_file_is_blamed_on_the_file_not_on_set(tmp_path, capsys):
    """Was "--set cmd_vel.linear: no board or part 'cmd_vel'" though no --set was given: with
    main = "mcm1" the file's [run.set] names an input the main board does not have."""
    text = shipped_text("elementall")
    p = tmp_path / "s.toml"
    p.write_text(text.replace('main = "rcm"', 'main = "mcm1"', 1))
    err = _err(capsys, ["run", str(p), "--duration", "1ms"])
    line = text[:text.index('"cmd_vel.linear" = ')].count("\n") + 1
    assert f"s.toml:{line}: [run.set] cmd_vel.linear: no board or part 'cmd_vel'" in err, err
    assert "--set" not in err, err


class _WrappedMotor:
    """A registered motor kind that is not a DcMotor subclass: it forwards to one it holds."""

    def __init__(self, kernel, name, **kw):
        from mcusim.plant.dcmotor import DcMotor
        object.__setattr__(self, "_m", DcMotor(kernel, name=name, **kw))

    def __getattr__(self, k):
        return getattr(self._m, k)


def test_the_kind_check_of_references_leaves_parts_of_registered_kinds_alone(tmp_path, monkeypatch):
    """The check refuses a built-in kind of the wrong sort (a bridge named as a motor) only: a
    plugin's motor kind drives a bridge and an encoder as before, and a divider takes any part
    with a voltage (another divider)."""
    monkeypatch.setattr(kinds, "_registered", {})
    kinds.register("part", "wrapped-motor", _WrappedMotor)
    p = tmp_path / "b.toml"
    p.write_text(shipped_text("pro-mini").replace('kind = "dcmotor"', 'kind = "wrapped-motor"', 1))
    sim = mcusim.load(str(p), firmware=False)
    sim.run(seconds="2ms")
    sim.close()
    text = shipped_text("elementall")
    at = text.index('kind = "divider"')
    end = text.index("\n[", at)
    chained = text[:end] + '\n\n[[part]]\nname = "vdiv2"\nkind = "divider"\nsource = "vbat_divider"\nr_top = 10000\nr_bottom = 10000\n' + text[end:]
    p.write_text(chained)
    sim = mcusim.load(str(p))
    sim.run(seconds="1ms")
    assert 0 < sim.part("vdiv2").voltage() < sim.part("vbat_divider").voltage()
    sim.close()


def test_a_mistake_inside_a_members_own_board_file_is_named_at_that_file_first(tmp_path, capsys):
    """From review: the system file's member line came first, so an editor jumped there."""
    pm = tmp_path / "pm.toml"
    pm.write_text(shipped_text("pro-mini").replace("counts_per_rev = ", "counts_per_rev = -", 1))
    text = shipped_text("elementall")
    p = tmp_path / "s.toml"
    p.write_text(text.replace('board = "pro-mini"', f'board = "{pm}"', 1))
    err = _err(capsys, ["run", str(p), "--duration", "1ms"])
    assert err.startswith(f"mcusim: error: {pm}:"), err


def test_a_part_listed_twice_in_a_list_of_parts_is_refused(tmp_path, capsys):
    """A rover body given one wheel motor twice ran with exit status 0: the body set that motor's
    load twice and never turned (yaw 0 on a turning run). Each listed part counts once."""
    text = shipped_text("rover-diff")
    start = text.index("motors = [")
    old = text[start:text.index("]", start) + 1]
    first = old[old.index('"'):old.index('"', old.index('"') + 1) + 1]
    p = tmp_path / "s.toml"
    p.write_text(text.replace(old, f"motors = [{first}, {first}]", 1))
    err = _err(capsys, ["run", str(p), "--duration", "1ms"])
    line = text[:start].count("\n") + 1
    assert f"s.toml:{line}: part body: motors lists {first.strip(chr(34))!r} twice" in err, err


@pytest.mark.parametrize("old,new,message", [
    ("counts_per_rev = 64", 'counts_per_rev = "64"',
     "encoder1: counts_per_rev = '64': expected an integer, not text (write it without quotes)"),
    ("irqs = { update = 29", 'irqs = { update = "29"',
     "irqs.update = '29': expected an integer, not text (write it without quotes)"),
])
def test_a_number_written_as_text_in_a_profile_is_refused(tmp_path, capsys, old, new, message):
    """A TOML string where a number belongs ran as the number: boards.md says every value has
    its type (a --set value is text and is read as one)."""
    err, line = _edited_run_error(tmp_path, capsys, "nucleo-f746", old, new, "b.toml")
    assert f"b.toml:{line}:" in err and message in err, err


def _table_line(text: str, marker: str) -> int:
    """The line of the [[...]] header of the table holding ``marker``."""
    at = text.index(marker)
    return text[:text.rindex("[[", 0, at)].count("\n") + 1


@pytest.mark.parametrize("board,old,new,located", [
    # a second peripheral taking port A, at its table
    ("nucleo-f746", 'port = "B"', 'port = "A"', ("table", 'port = "A"\n[[peripheral]]\nname = "GPIOC"',
                                                  "peripheral GPIOB (stm32-gpio): GPIOB: port A is declared twice")),
    # a clock the MCU does not have, at its key
    ("nucleo-f746", 'clock = "APB2_TIM"', 'clock = "APB9_TIM"', ("key", 'clock = "APB9_TIM"',
                                                                  "peripheral TIM1: no clock 'APB9_TIM'")),
    # a member's own set value out of range, at its key in the system file
    ("rover-diff", '"firmware.i2c_address" = 0x08', '"firmware.i2c_address" = 0x200',
     ("key", '"firmware.i2c_address" = 0x200', "member left: set: firmware.i2c_address = 512: must be from 8 to 119")),
    # a pin a member's MCU does not have, in the system's [pins]
    ("rover-diff", '"rcm.GPIO3_0" =', '"rcm.GPIO9_99" =',
     ("key", '"rcm.GPIO9_99" =', "[pins] 'rcm.GPIO9_99': LPC4337 has no pin 'GPIO9_99'")),
])
def test_mistakes_found_while_building_name_the_profiles_line(tmp_path, capsys, board, old, new, located):
    """These said what was wrong but not where (no file, or no line, or no member)."""
    text = shipped_text(board).replace(old, new, 1)
    p = tmp_path / "b.toml"
    p.write_text(text)
    err = _err(capsys, ["run", str(p), "--duration", "1ms"])
    how, marker, message = located
    line = _table_line(text, marker) if how == "table" else text[:text.index(marker)].count("\n") + 1
    assert f"b.toml:{line}: {message}" in err, err


@pytest.mark.parametrize("old, new, needle", [
    # was accepted without --firmware, and with it blamed on the TIM1 table ("overlaps another peripheral")
    ("base = 0x2004C000", "base = 0x40010000",
     "[[memory]] SRAM2: 0x40010000-0x40013fff overlaps peripheral TIM1 at 0x40010000-0x400103ff"),
    # was accepted
    ('name = "SRAM2"', 'name = "SRAM1"', "[[memory]] #5: name 'SRAM1' is taken by another [[memory]] table"),
    # an address shown as an address (was base 1073888256, and 2.81475e+14)
    ("base = 0x2004C000", "base = 0x40023C00", "[[memory]] SRAM2: base 0x40023c00: expected a 0x1000-aligned address"),
    ("base = 0x2004C000", "base = 0xFFFFFFFFF000", "[[memory]] SRAM2: base 0xfffffffff000: expected a 0x1000-aligned"),
])
def test_a_memory_region_over_a_peripheral_or_named_twice_is_named_at_its_line(tmp_path, capsys, old, new, needle):
    err, line = _edited_run_error(tmp_path, capsys, "nucleo-f746", old, new, "m.toml")
    assert f"m.toml:{line}: {needle}" in err, err
    p = tmp_path / "m.toml"     # the same with a compiled image: the file is refused alike
    assert _err(capsys, ["run", str(p), "--duration", "1ms", "--firmware", "controlmotor"]) == err
