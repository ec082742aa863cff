"""Trace outputs: GTKWave save file, CSV on a uniform grid, register-access log, plots, and the
VCD read back by sigrok's PWM decoder."""

import csv
import io
import json
import re
import shutil
import subprocess
from fractions import Fraction
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import mcusim
from mcusim.csvtrace import CsvTrace, read_csv
from mcusim.errors import ConfigError
from mcusim.kernel import PRIO_OBSERVE
from mcusim.reglog import RegisterLog, load_logged
from mcusim.trace import write_gtkw

TIM1, GPIOE = 0x40010000, 0x40021000
CR1, SR, EGR, CCMR1, CCER, ARR, CCR1, BDTR = 0x00, 0x10, 0x14, 0x18, 0x20, 0x2C, 0x34, 0x44
UNITS = ("_rad", "_rpm", "_a", "_v", "_pct", "_m", "_s", ".soc")


def pe9_pwm(sim, arr, ccr):
    """TIM1 CH1 in PWM mode 1 on PE9 (AF1), programmed through the bus as a bare-metal test would."""
    m = sim.mcu
    m.write32(GPIOE + 0x24, (m.read32(GPIOE + 0x24) & ~(0xF << 4)) | (1 << 4))   # AFR[1]: PE9 = AF1
    m.write32(GPIOE, (m.read32(GPIOE) & ~(3 << 18)) | (2 << 18))                  # MODER9 = AF
    m.write32(TIM1 + ARR, arr)
    m.write32(TIM1 + CCR1, ccr)
    m.write32(TIM1 + CCMR1, 0x60)          # OC1M = PWM mode 1
    m.write32(TIM1 + EGR, 1)               # UG
    m.write32(TIM1 + SR, 0)
    m.write32(TIM1 + CCER, 1)              # CC1E
    m.write32(TIM1 + BDTR, 1 << 15)        # MOE
    m.write32(TIM1 + CR1, 1)               # CEN


def lines_of(path):
    with open(path) as f:
        return [json.loads(line) for line in f]


def all_peripherals(sim):
    return [p for member in sim.members.values() for p in member["mcu"].periph.values()]


# --- CSV ------------------------------------------------------------------------------------------------

def test_csv_rows_lie_exactly_on_the_grid_with_units_in_the_header(tmp_path):
    sim = mcusim.load("nucleo-f746", overrides={"/motor1/set_pos": 1.57})
    path = tmp_path / "run.csv"
    tr = CsvTrace(sim, path, sample="1ms", keep=True)
    sim._traces.append(tr)
    sim.run(seconds="20ms")
    motor = sim.part("motor1")
    final = (motor.output_angle, motor.current)
    sim.close()
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    header, body = rows[0], rows[1:]
    assert header[0] == "time_s"
    assert all(c.endswith(UNITS) for c in header), header
    for col in ("motor1.angle_rad", "motor1.speed_rpm", "motor1.current_a", "motor2.angle_rad",
                "motor1.setpoint_rad", "motor1.duty_pct", "motor1.fw_position_rad", "motor2.setpoint_rad"):
        assert col in header
    # one row per millisecond, k = 0..20, written exactly and sampled at exactly k·216 000 ticks
    assert len(body) == 21
    assert [Fraction(r[0]) for r in body] == [Fraction(k, 1000) for k in range(21)]
    assert [r[0] for r in body][:4] == ["0", "0.001", "0.002", "0.003"]
    assert tr.ticks == [k * 216_000 for k in range(21)]
    # the last row is the state at 20 ms after every event of that tick (PRIO_OBSERVE): the end state
    i_angle, i_current = header.index("motor1.angle_rad"), header.index("motor1.current_a")
    assert float(body[-1][i_angle]) == final[0] and float(body[-1][i_current]) == final[1]
    assert final[0] > 0
    # the set point arrives with the first executor spin; the PID then asks for full duty
    sp = [float(r[header.index("motor1.setpoint_rad")]) for r in body]
    assert sp[0] == 0.0 and sp[-1] == 1.57
    assert float(body[-1][header.index("motor1.duty_pct")]) == 100.0
    # published position: empty before the first publication, then a number
    assert read_csv(path)["motor1.fw_position_rad"][-1] is not None


def test_csv_attached_mid_run_starts_at_the_next_grid_point_and_needs_whole_ticks(tmp_path):
    sim = mcusim.load("nucleo-f746", firmware=False)
    sim.run(seconds="2.5ms")
    tr = CsvTrace(sim, None, sample="1ms", keep=True)
    sim.run(seconds="2.5ms")
    assert [r[0] for r in tr.rows] == [0.003, 0.004, 0.005]
    assert tr.ticks == [3 * 216_000, 4 * 216_000, 5 * 216_000]
    assert tr.column("motor1.angle_rad") == [0.0, 0.0, 0.0]
    tr.close()
    with pytest.raises(ConfigError, match="base ticks"):
        CsvTrace(sim, tmp_path / "x.csv", sample="1ns")       # 0.216 ticks
    with pytest.raises(ConfigError, match="keep=True"):
        CsvTrace(sim, None)


def test_csv_of_the_pro_mini_has_the_velocity_loop(tmp_path):
    sim = mcusim.load("pro-mini", overrides={"velocity": 10})
    tr = CsvTrace(sim, tmp_path / "m.csv", sample="1ms", keep=True)
    sim._traces.append(tr)
    sim.run(seconds="30ms")
    sim.close()
    cols = read_csv(tmp_path / "m.csv")
    for c in ("motor.angle_rad", "motor.speed_rpm", "motor.current_a", "ibt2.supply_v",
              "motor.setpoint_rpm", "motor.velocity_rpm", "motor.duty_pct", "motor.fw_current_a"):
        assert c in cols
    assert cols["time_s"] == [k / 1000 for k in range(31)]
    assert cols["ibt2.supply_v"][-1] == 12.0
    assert cols["motor.setpoint_rpm"][0] == 0.0 and cols["motor.setpoint_rpm"][-1] == pytest.approx(10, abs=0.01)
    assert cols["motor.duty_pct"][-1] > 0 and cols["motor.speed_rpm"][-1] > 0
    assert cols == tr.as_dict()


# --- register log -------------------------------------------------------------------------------------

def test_register_log_has_the_hal_start_up_of_tim1_and_later_encoder_reads(tmp_path):
    sim, log = load_logged("nucleo-f746", tmp_path / "regs.jsonl")
    sim.run(seconds="6ms")
    sim.close()
    lines = lines_of(tmp_path / "regs.jsonl")
    assert len(lines) == log.lines
    cen = [x for x in lines if x["reg"] == "TIM1.CR1" and x["op"] == "write" and "CEN" in x["changed"]]
    assert cen == [{"t_s": 0.0, "cycle": 0, "mcu": "nucleo-f746", "addr": "0x40010000", "reg": "TIM1.CR1",
                    "op": "write", "value": "0x00000081", "changed": {"CEN": [0, 1]}}]
    arr = next(x for x in lines if x["reg"] == "TIM1.ARR" and x["op"] == "write")
    assert arr["addr"] == "0x4001002c" and arr["value"] == "0x000010df" and arr["changed"] == {"ARR": [0, 4319]}
    moe = next(x for x in lines if x["reg"] == "TIM1.BDTR" and x["op"] == "write")
    assert moe["changed"] == {"MOE": [0, 1]}
    # HAL order: CEN is set after the channels are configured and enabled
    order = [x["reg"] for x in lines if x["reg"].startswith("TIM1.") and x["op"] == "write"]
    assert order.index("TIM1.CCER") < order.index("TIM1.CR1", 1)
    # the 5 ms PID pass reads the encoder counters (TIM3.CNT at 0x40000424), at the right cycle
    cnt = [x for x in lines if x["reg"] == "TIM3.CNT" and x["op"] == "read" and x["t_s"] > 0]
    assert cnt and all(x["addr"] == "0x40000424" for x in cnt)
    for x in lines:
        assert x["cycle"] == round(x["t_s"] * 216e6)
        assert set(x) == {"t_s", "cycle", "mcu", "addr", "reg", "op", "value"} | ({"changed"} if x["op"] == "write" else set())
        assert re.fullmatch(r"0x[0-9a-f]{8}", x["addr"]) and x["value"].startswith("0x")


def test_register_log_attached_after_load_misses_start_up_only(tmp_path):
    sim = mcusim.load("nucleo-f746")
    log = RegisterLog(sim, tmp_path / "late.jsonl")
    sim._traces.append(log)
    sim.run(seconds="6ms")
    sim.close()
    lines = lines_of(tmp_path / "late.jsonl")
    assert not any(x["reg"] == "TIM1.CR1" for x in lines)
    assert any(x["reg"] == "TIM3.CNT" for x in lines)


def test_register_log_filter_names_peripherals_and_register_prefixes(tmp_path):
    sim, _ = load_logged("nucleo-f746", tmp_path / "f.jsonl", filter=["tim1.ccr1", "GPIOE"])
    # only matching peripherals carry a hook: the others cost nothing
    hooked = {p.name for p in all_peripherals(sim) if p.access_log is not None}
    assert hooked == {"TIM1", "GPIOE"}
    sim.run(seconds="6ms")
    sim.close()
    regs = {x["reg"] for x in lines_of(tmp_path / "f.jsonl")}
    assert "TIM1.CCR1" in regs and any(r.startswith("GPIOE.") for r in regs)
    assert all(r == "TIM1.CCR1" or r.startswith("GPIOE.") for r in regs), regs
    # a PERIPH.REG prefix and a glob
    sim, _ = load_logged("nucleo-f746", tmp_path / "g.jsonl", filter="TIM1.CCR,gpio?")
    sim.run(seconds="1ms")
    sim.close()
    regs = {x["reg"] for x in lines_of(tmp_path / "g.jsonl")}
    assert {"TIM1.CCR1", "TIM1.CCR2"} <= regs
    assert {r.split(".")[0] for r in regs} <= {"TIM1", "GPIOA", "GPIOB", "GPIOD", "GPIOE", "GPIOF"}
    assert not any(r.startswith("TIM1.C") and not r.startswith("TIM1.CCR") for r in regs)


def test_a_member_qualified_filter_hooks_only_that_members_peripheral():
    """"mcm1.TIMER1" once hooked every peripheral of mcm1: its ports then counted as watched, and
    the fast engine stopped serving mcm1's encoder edges in closed form."""
    sim = mcusim.load("elementall")
    log = RegisterLog(sim, io.StringIO(), filter="mcm1.TIMER1")
    hooked = {(m, p.name) for m, member in sim.members.items()
              for p in member["mcu"].periph.values() if p.access_log is not None}
    assert hooked == {("mcm1", "TIMER1")}
    log.close()


def test_a_filter_matches_the_pin_registers_a_model_decodes_from_the_offset():
    """The LPC43xx GPIO makes its byte and word pin registers (B<k>, W<k>) when first accessed:
    a filter naming them (a glob too) hooks the GPIO and logs those accesses."""
    sim = mcusim.load("ciaa-edu", firmware=False)
    out = io.StringIO()
    log = RegisterLog(sim, out, filter="GPIO.W*,gpio.b3")
    gpio = sim.mcu.periph["GPIO"]
    base = next(base for base, _size, p in sim.mcu.bus._entries if p is gpio)
    sim.mcu.write32(base + 0x1000 + 4 * 3, 1)       # W3: GPIO0[3]
    sim.mcu.read8(base + 3)                          # B3
    sim.mcu.read8(base + 4)                          # B4: not asked for
    log.close()
    assert [x["reg"] for x in map(json.loads, out.getvalue().splitlines())] == ["GPIO.W3", "GPIO.B3"]


@pytest.mark.parametrize("filt,says", [
    ("mcm1.USART2.FCR", "mcm1 has no peripheral USART2"),
    ("rcm.TWI", "rcm has no peripheral TWI"),
    ("mcm1.TIMER1.TCNT9", "TIMER1 has no register TCNT9"),
])
def test_a_member_qualified_filter_naming_what_that_board_lacks_says_so(filt, says):
    sim = mcusim.load("elementall")
    with pytest.raises(ConfigError, match=says):
        RegisterLog(sim, io.StringIO(), filter=filt)


def _log_lines(board, filt, overrides=None):
    out = io.StringIO()
    sim = mcusim.load(board, overrides=overrides or {})
    log = RegisterLog(sim, out, filter=filt)
    sim.run(seconds="3ms")
    log.close()
    return [json.loads(x) for x in out.getvalue().splitlines()]


_FULL = {}


@st.composite
def _filter_patterns(draw):
    """A filter pattern made from the rover's own names: a member, a peripheral, PERIPH.REG or
    MEMBER.PERIPH.REG, cut to a prefix, with a glob character put in here and there."""
    if "lines" not in _FULL:
        _FULL["lines"] = _log_lines("elementall", None)
    x = draw(st.sampled_from(_FULL["lines"]))
    member, (periph, reg) = x["mcu"], x["reg"].split(".", 1)
    text = draw(st.sampled_from([member, periph, f"{periph}.{reg}", f"{member}.{periph}",
                                 f"{member}.{periph}.{reg}"]))
    text = text[:draw(st.integers(1, len(text)))]
    if draw(st.booleans()):
        text = text.replace(".", draw(st.sampled_from("*?")), 1)    # a glob across the dot
    for _ in range(draw(st.integers(0, 2))):
        i = draw(st.integers(0, len(text) - 1))
        text = text[:i] + draw(st.sampled_from("*?")) + text[i + 1:]
    return draw(st.sampled_from([text, text.lower()]))


@settings(max_examples=30, deadline=None)
@given(pat=_filter_patterns())
def test_a_filtered_log_holds_exactly_the_accesses_of_the_full_log_that_its_pattern_matches(pat):
    """Which peripherals get a hook is decided from their registers' names: a glob's ? or * also
    matches the dot (TIMER1?TCNT1), and a member-qualified name hooks that member's peripheral."""
    from mcusim.reglog import _matcher
    match = _matcher([pat])
    want = [x for x in _FULL["lines"] if match(x["mcu"], *x["reg"].split(".", 1))]
    if not want:
        return      # refused as matching nothing (test_cli_outputs)
    assert _log_lines("elementall", pat) == want


def test_hardware_side_register_changes_are_not_logged(tmp_path):
    sim = mcusim.load("nucleo-f746", firmware=False)
    assert all(p.access_log is None for p in all_peripherals(sim))   # no log: nothing hooked
    log = RegisterLog(sim, tmp_path / "hw.jsonl")
    pe9_pwm(sim, 4319, 1080)
    n = log.lines
    assert n > 0
    sim.run(seconds="1ms")       # 50 update events: UIF, CC1IF set by the timer (set_bits)
    assert log.lines == n
    assert sim.mcu.read32(TIM1 + SR) & 1       # ... the firmware's read of SR is logged
    log.close()
    assert all(p.access_log is None for p in all_peripherals(sim))
    lines = lines_of(tmp_path / "hw.jsonl")
    assert len(lines) == n + 1
    assert lines[-1]["reg"] == "TIM1.SR" and lines[-1]["op"] == "read" and int(lines[-1]["value"], 16) & 1
    assert lines[-1]["cycle"] == 216_000


# --- a system: register log, CSV, plot and gtkw of the rover ----------------------------------------

@pytest.mark.heavy
def test_rover_register_log_csv_plot_and_gtkw(tmp_path):
    sim, _ = load_logged("elementall", tmp_path / "rover.jsonl", overrides={"cmd_vel.linear": 0})
    tr = CsvTrace(sim, tmp_path / "rover.csv", sample="10ms", keep=True)
    sim._traces.append(tr)
    vcd = sim.trace_vcd(tmp_path / "rover.vcd", sample="1ms")
    gtkw = vcd.write_gtkw()
    sim.run(seconds="0.2s")
    sim.close()
    lines = lines_of(tmp_path / "rover.jsonl")
    assert {x["mcu"] for x in lines} == {"rcm", "mcm1", "mcm2", "mcm3", "mcm4"}
    hz = {"rcm": 204e6, "mcm1": 16e6}
    for x in lines:
        if x["mcu"] in hz:
            assert x["cycle"] == int(x["t_s"] * hz[x["mcu"]] + 1e-6)
    # the controller probes the modules over I2C0 (0x400A1000); each module's TWI answers
    assert any(x["mcu"] == "rcm" and x["reg"] == "I2C0.DAT" and x["addr"] == "0x400a1008" for x in lines)
    twdr = [x for x in lines if x["mcu"] == "mcm2" and x["reg"] == "TWI.TWDR"]
    assert twdr and all(x["addr"] == "0x00bb" for x in twdr)
    # CSV: pose, odometry, battery, module set points
    cols = read_csv(tmp_path / "rover.csv")
    for c in ("body.x_m", "body.y_m", "body.yaw_rad", "odometry.x_m", "odometry.yaw_rad",
              "battery.voltage_v", "battery.soc", "battery.measured_v", "mcm1.motor.setpoint_rpm",
              "mcm4.motor.duty_pct", "mcm1.ibt2.supply_v", "cmd_vel.linear_m_s"):
        assert c in cols
    assert cols["time_s"] == [k / 100 for k in range(21)]
    assert cols["battery.measured_v"][0] is None and cols["battery.measured_v"][-1] == pytest.approx(12.7, abs=0.1)
    # plot from the CSV file: one row per wheel, then path and battery
    from mcusim.plot import plot_run
    fig = plot_run(tmp_path / "rover.csv", tmp_path / "rover.png")
    labels = {(a.get_xlabel(), a.get_ylabel()) for a in fig.axes}
    assert ("x (m)", "y (m)") in labels and ("time (s)", "voltage (V)") in labels
    path_ax = next(a for a in fig.axes if a.get_xlabel() == "x (m)")
    assert [t.get_text() for t in path_ax.get_legend().get_texts()] == ["true pose", "odometry"]
    assert sum(a.get_ylabel() == "speed (rpm)" for a in fig.axes) == 4
    assert (tmp_path / "rover.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # gtkw: one group per board scope of the system
    with open(gtkw) as f:
        text = f.read()
    for member in ("rcm", "mcm1", "mcm2", "mcm3", "mcm4"):
        assert f"-elementall.{member}\n" in text
    assert "elementall.mcm3.PB1\n" in text and "elementall.rcm.GPIO3_3\n" in text
    assert "elementall.plant.\\estop.enable_out\n" in text      # escaped as GTKWave names it


# --- plot -----------------------------------------------------------------------------------------------

def test_plot_of_the_nucleo_run_has_position_current_and_duty_panels(tmp_path):
    sim = mcusim.load("nucleo-f746", overrides={"/motor1/set_pos": 1.57, "/motor2/set_pos": -0.5})
    tr = CsvTrace(sim, None, sample="1ms", keep=True)
    sim._traces.append(tr)
    sim.run(seconds="40ms")
    sim.close()
    from mcusim.plot import plot_run
    png = tmp_path / "run.png"
    fig = plot_run(tr, png, title="nucleo-f746")
    data = png.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 10_000
    axes = {(a.get_title(), a.get_xlabel(), a.get_ylabel()): a for a in fig.axes if a.get_title()}
    pos = axes[("motor1: position", "time (s)", "angle (rad)")]
    assert [t.get_text() for t in pos.get_legend().get_texts()] == [
        "motor1 set point", "motor1 position (firmware)", "motor1 angle (plant)"]
    cur = axes[("motor2: current and duty", "time (s)", "current (A)")]
    assert [t.get_text() for t in cur.get_legend().get_texts()] == ["motor2 current", "motor2 duty"]
    assert {a.get_ylabel() for a in fig.axes} == {"angle (rad)", "current (A)", "duty (%)"}
    # the set point line carries the commanded value
    sp_line = next(ln for ln in pos.get_lines() if ln.get_label() == "motor1 set point")
    assert sp_line.get_ydata()[-1] == 1.57


# --- gtkw -----------------------------------------------------------------------------------------------

def test_gtkw_groups_pins_interrupts_and_plant_with_full_names(tmp_path):
    sim = mcusim.load("nucleo-f746", firmware=False)
    vcd_path = tmp_path / "n.vcd"
    tr = sim.trace_vcd(vcd_path)
    sim.run(seconds="1ms")
    sim.close()
    path = write_gtkw(tr)
    assert path == str(tmp_path / "n.gtkw")
    with open(path) as f:
        text = f.read()
    lines = text.splitlines()
    assert '[dumpfile] "n.vcd"' in lines           # relative to the layout: the pair can be moved
    assert '[savefile] "n.gtkw"' in lines and "[timestart] 0" in lines
    # three groups, each opened with @800200 and closed with @1000200
    groups = [lines[i + 1][1:] for i, x in enumerate(lines) if x == "@800200"]
    assert groups == ["nucleo-f746", "interrupts", "plant"]
    assert [lines[i + 1][1:] for i, x in enumerate(lines) if x == "@1000200"] == groups
    # every traced signal by its full hierarchical name, in its group, with its display flags
    assert {name for _, name, _ in tr.signals} <= set(lines)
    assert len(tr.signals) == 10 + 12 + 6
    def group_of(name):
        i = lines.index(name)
        return next(lines[j + 1][1:] for j in range(i, -1, -1) if lines[j] == "@800200")
    for pin in ("PE9", "PB4", "PD13"):
        assert group_of(f"nucleo-f746.{pin}") == "nucleo-f746"
    assert group_of("nucleo-f746.irq.TIM1_UP") == "interrupts"
    assert group_of("nucleo-f746.plant.\\motor1.angle_rad") == "plant"
    flag = {}
    current = None
    for x in lines:
        if x.startswith("@"):
            current = x
        elif x.startswith("nucleo-f746"):
            flag[x] = current
    assert flag["nucleo-f746.PE9"] == "@28" and flag["nucleo-f746.irq.TIM3"] == "@28"
    assert flag["nucleo-f746.plant.\\motor2.current_a"] == "@8420"      # analog step
    assert flag["nucleo-f746.plant.\\bridgeA.ocd"] == "@28"
    # the VCD declares the same names
    from vcd.reader import TokenKind, tokenize
    declared, scope = set(), []
    with open(vcd_path, "rb") as f:
        for tok in tokenize(f):
            if tok.kind is TokenKind.SCOPE:
                scope.append(tok.scope.ident)
            elif tok.kind is TokenKind.UPSCOPE:
                scope.pop()
            elif tok.kind is TokenKind.VAR:   # as GTKWave names it: a name holding a dot escaped
                ref = tok.var.reference
                declared.add(".".join(scope) + "." + ("\\" + ref if "." in ref else ref))
    assert declared == {name for _, name, _ in tr.signals}


# --- sigrok ---------------------------------------------------------------------------------------------

def test_sigrok_pwm_decoder_reads_frequency_and_duty_of_a_timer_pin(tmp_path):
    """sigrok-cli reads our VCD as written (ps timescale, real variables skipped; channels are
    named by the variable alone): TIM1 CH1 at 50 kHz with CCR1 = 1296 of 4320 is 30 % on PE9."""
    if shutil.which("sigrok-cli") is None:
        pytest.skip("sigrok-cli is not installed")
    sim = mcusim.load("nucleo-f746", firmware=False)
    vcd = tmp_path / "pwm.vcd"
    sim.trace_vcd(vcd)
    pe9_pwm(sim, 4319, 1296)
    sim.run(seconds="2ms")
    sim.close()
    # downsample=1000: 1 ns samples instead of 1 ps (edges fall on 4.63 ns ticks; exact here)
    out = subprocess.run(["sigrok-cli", "-I", "vcd:downsample=1000", "-i", str(vcd),
                          "-P", "pwm:data=PE9", "-A", "pwm"],
                         capture_output=True, text=True, timeout=60, check=True).stdout
    duties = [float(m) for m in re.findall(r"pwm-1: ([\d.]+)%", out)]
    scale = {"s": 1, "ms": 1e-3, "μs": 1e-6, "us": 1e-6, "ns": 1e-9}
    periods = [float(v) * scale[u] for v, u in re.findall(r"pwm-1: ([\d.]+) (s|ms|μs|us|ns)\b", out)]
    assert len(duties) >= 95 and len(periods) >= 95          # 100 periods in 2 ms
    assert all(d == pytest.approx(30.0, abs=0.01) for d in duties)
    assert all(1 / p == pytest.approx(50_000, rel=1e-3) for p in periods)


def test_a_plot_of_the_battery_alone_spans_the_width_of_the_figure(tmp_path):
    """ciaa-edu on the bench has no motors: its one panel, the battery, took the left half of a
    two-column grid and left the right half empty."""
    sim = mcusim.load("ciaa-edu")
    tr = CsvTrace(sim, None, sample="1ms", keep=True)
    sim._traces.append(tr)
    sim.run(seconds="20ms")
    sim.close()
    from mcusim.plot import plot_run
    fig = plot_run(tr)
    (ax,) = fig.axes
    assert ax.get_title() == "battery"
    assert ax.get_subplotspec().colspan == range(2)


def _vcd_changes_per_timestamp(path):
    """{timestamp: [value change lines]} of a VCD's body."""
    out, ts = {}, None
    for line in Path(path).read_text().split("$enddefinitions $end")[1].splitlines():
        if line.startswith("#"):
            ts = int(line[1:])
        elif line and ts is not None and line[0] in "01":
            out.setdefault(ts, []).append(line)
    return out


def _tim1_pwm2_on_pe9(sim):
    """TIM1 CH1 on PE9 (AF1) in PWM2, PSC 3, ARR 333, CCR1 100, started."""
    m = sim.mcu
    m.write32(GE, (m.read32(GE) & ~(3 << 18)) | (2 << 18))
    m.write32(GE + 0x24, (m.read32(GE + 0x24) & ~(0xF << 4)) | (1 << 4))
    for off, v in ((0x28, 3), (0x2C, 333), (0x34, 100), (0x18, 7 << 4), (0x20, 1), (0x44, 1 << 15),
                   (0x14, 1), (0x00, 1)):
        m.write32(T1 + off, v)
    sim.run(cycles=3 * 334 * 4)
    while m.read32(T1 + 0x24) != 100:           # the first tick of CNT = 100: the match's
        sim.run(cycles=1)
    return sim.kernel.now


T1, GE = 0x40010000, 0x40021000


@pytest.mark.parametrize("engine", ["fast", "reference"])
@pytest.mark.parametrize("from_python", [False, True])
def test_a_pin_set_and_cleared_on_one_tick_is_no_pulse_in_the_vcd(tmp_path, engine, from_python):
    """TIM1 CH1 (PE9) in PWM2 goes active at the compare match CNT = CCR1; OC1M written to PWM1 on
    that very tick makes it inactive again. The chip's output changes on clock edges: no pulse.
    Edge by edge the VCD had shown one of zero width (two values of PE9 at one timestamp; a
    review found it in a compiled image, the fast engine wrote nothing), and so did both engines
    when the write came from Python after a run that ended on the match."""
    sim = mcusim.load("nucleo-f746", firmware=False, engine=engine)
    path = tmp_path / "t.vcd"
    sim.trace_vcd(path)
    if from_python:
        _tim1_pwm2_on_pe9(sim)
        assert sim.pin("PE9").level == 1
        sim.mcu.write32(T1 + 0x18, 6 << 4)
    else:
        probe = mcusim.load("nucleo-f746", firmware=False, engine=engine)
        t = _tim1_pwm2_on_pe9(probe)
        probe.close()
        # the write inside the run, after the match's event on its tick
        sim.kernel.at(t, lambda: sim.mcu.write32(T1 + 0x18, 6 << 4), prio=PRIO_OBSERVE)
        _tim1_pwm2_on_pe9(sim)
    assert sim.pin("PE9").level == 0
    sim.run(cycles=4000)
    sim.close()
    for ts, lines in _vcd_changes_per_timestamp(path).items():
        names = [ln[1:] for ln in lines]
        assert len(names) == len(set(names)), f"two values of one signal at #{ts}: {lines}"
