"""The gdb server of a compiled image: the remote serial protocol spoken by a client in Python (no
gdb needed), and a gdb-multiarch batch session when gdb-multiarch is installed."""

from __future__ import annotations

import re
import shutil
import socket
import subprocess
import sys
import threading
from pathlib import Path

import pytest
from rsp_client import Rsp

import mcusim
from mcusim.elf.gdb import DebuggerKill, GdbServer

BIN = Path(__file__).parent / "elf_bin"
TICKS = str(BIN / "ticks.elf")


def session(script, duration="50ms"):
    """Run ``script(client, symbols)`` against a simulation of ticks.elf served on a free port."""
    sim = mcusim.load("nucleo-f746", firmware=TICKS)
    srv = GdbServer(sim, 0)
    out, errors = {"kernel": sim.kernel}, []

    def client():
        c = Rsp(srv.port)
        try:
            script(c, sim.firmware.symbols, out)
        except BaseException as exc:   # noqa: BLE001 (reported by the test below)
            errors.append(exc)
        finally:
            c.close()
    t = threading.Thread(target=client)
    t.start()
    srv.wait_for_client(quiet=True)
    try:
        sim.run(seconds=duration)
    finally:
        sim.close()
        srv.finish()
        t.join(30)
    if errors:
        raise errors[0]
    return sim, out


def le32(hexword):
    return int.from_bytes(bytes.fromhex(hexword), "little")


def test_halted_at_reset_with_sp_and_pc_from_the_vector_table():
    def script(c, syms, out):
        out["stop"] = c.ask("?")
        regs = c.ask("g")
        out["sp"], out["pc"] = le32(regs[13 * 8:14 * 8]), le32(regs[15 * 8:16 * 8])
        out["msp"], out["control"] = le32(c.ask("p11")), le32(c.ask("p16"))    # regnums 17, 22
        c.ask("D")
    sim, out = session(script)
    assert out["stop"] == "T05"
    assert out["sp"] == 0x20050000 and out["pc"] == sim.firmware.symbols["Reset_Handler"]
    assert out["msp"] == out["sp"] and out["control"] == 0        # thread mode on MSP after reset


def test_the_target_description_has_the_fpu_registers_gdb_needs_for_float_variables():
    """gdb's ARM target finds d0-d15 and fpscr in an org.gnu.gdb.arm.vfp feature (it then shows
    s0-s31 as their halves and reads hard-float arguments, DWARF registers 64-95, from them)."""
    def script(c, syms, out):
        xml = c.ask("qXfer:features:read:target.xml:0,fff")[1:]
        out["vfp"] = '<feature name="org.gnu.gdb.arm.vfp">' in xml
        out["d0"] = re.search(r'<reg name="d0" bitsize="64" regnum="(\d+)"', xml)
        n = int(out["d0"].group(1))
        # d1 = s3:s2; write it through P, read the halves through the core
        assert c.ask(f"P{n + 1:x}=" + (0x4000000040400000).to_bytes(8, "little").hex()) == "OK"
        out["p"] = c.ask(f"p{n + 1:x}")
        out["g_len"] = len(c.ask("g"))
        c.ask("D")
    sim, out = session(script, duration="1us")
    assert out["vfp"] and out["d0"]
    assert sim.mcu.cpu.reg("s2") == 0x40400000 and sim.mcu.cpu.reg("s3") == 0x40000000   # 3.0f, 2.0f
    assert out["p"] == (0x4000000040400000).to_bytes(8, "little").hex()
    assert out["g_len"] == 2 * (23 * 4 + 16 * 8 + 4)       # 23 core and system registers


def test_simulated_time_stands_still_while_halted_and_a_breakpoint_stops_at_its_address():
    times = []

    def script(c, syms, out):
        times.append(out["kernel"].now)
        assert c.ask(f"Z0,{syms['SysTick_Handler']:x},2") == "OK"
        out["stop"] = c.ask("c")
        out["pc"] = le32(c.ask("pf"))
        out["xpsr"] = le32(c.ask("p10"))
        times.append(out["kernel"].now)
        c.ask(f"z0,{syms['SysTick_Handler']:x},2")
        c.ask("D")
    sim, out = session(script)
    assert times[0] == 0                               # halted at reset: nothing ran yet
    assert out["stop"].startswith("T05swbreak")
    assert out["pc"] == sim.firmware.symbols["SysTick_Handler"]
    assert out["xpsr"] & 0x1FF == 15                   # in the SysTick exception
    # the first SysTick wrap is 216000 cycles after the enabling write: time reached it, no further
    assert 216000 < times[1] < 216000 + 1000


def test_step_executes_one_instruction():
    def script(c, syms, out):
        pc0 = le32(c.ask("pf"))
        out["stop"] = c.ask("vCont;s:1")
        out["step"] = le32(c.ask("pf")) - pc0
        c.ask("D")
    _, out = session(script)
    assert out["stop"] == "T05" and out["step"] in (2, 4)


def test_memory_reads_reach_ram_and_peripherals_through_the_models():
    def script(c, syms, out):
        c.ask(f"Z0,{syms['TIM2_IRQHandler']:x},2")
        c.ask("c")
        out["sr_before"] = le32(c.ask("m40000010,4"))          # TIM2.SR: UIF set
        assert c.ask("M40000010,4:00000000") == "OK"            # cleared through the model
        out["sr_after"] = le32(c.ask("m40000010,4"))
        out["ticks"] = le32(c.ask(f"m{syms['ticks']:x},4"))
        assert c.ask(f"M{syms['ticks']:x},4:e8030000") == "OK"
        c.ask(f"z0,{syms['TIM2_IRQHandler']:x},2")
        out["unmapped"] = c.ask("m60000000,4")
        c.ask("D")
    sim, out = session(script, duration="20ms")
    assert out["sr_before"] & 1 and not out["sr_after"] & 1
    assert out["unmapped"].startswith("E")
    assert sim.firmware.topic("/ticks") > 1000                  # the write to RAM stuck


MALFORMED = ["m0,zz", "m20000000", "m-1,4", "m20000000,4,4", "pzz", "P0=zz", "P=00", "Gzz",
             "M20000000,zz:00", "M20000000,2:zz", "M20000000,2:00", "M20000000,2", "Z0,zz,2",
             "z0,1", "Zx,20000000,2", "Z2,20000000,0", "c12g4", "sx"]


def test_a_packet_whose_fields_do_not_parse_gets_an_error_reply_and_the_session_goes_on():
    """The remote protocol's convention for a request the stub cannot carry out: ``E NN``. Each
    malformed packet (bad hex, fields missing or extra, a write whose data is not as long as it
    says, an empty watch range) is answered E01; the next request is served as usual."""
    def script(c, syms, out):
        out["replies"] = {p: c.ask(p) for p in MALFORMED}
        out["after"] = c.ask(f"m{syms['ticks']:x},4")
        c.ask("D")
    _, out = session(script, duration="5ms")
    assert out["replies"] == {p: "E01" for p in MALFORMED}
    assert len(out["after"]) == 8 and not out["after"].startswith("E")


def _is_str_immediate_t1(halfword: int) -> bool:
    """Armv7-M STR (immediate), encoding T1: 0b01100 imm5 Rn Rt."""
    return halfword >> 11 == 0b01100


def test_watchpoints_on_ram_and_on_a_peripheral_register_stop_at_the_accessing_instruction():
    """gdb takes an ARM watchpoint as firing before the access completes (its arm target's
    'non-steppable' watchpoints): it steps the reported instruction itself, then shows the stop.
    So the stub stops with the accessing instruction not retired and PC at it; a stop after it had
    made gdb step once more and show the next instruction (outside the handler after its last
    store). Continuing without removing the watchpoint runs that instruction and goes on."""
    def script(c, syms, out):
        c.ask(f"Z2,{syms['ticks']:x},4")
        out["ram"] = [c.ask("c") for _ in range(2)][-1]          # (the first: start-up's .bss clear)
        out["ram_pc"] = le32(c.ask("pf"))
        out["again"] = c.ask("c")                                 # the next SysTick's store
        out["again_pc"] = le32(c.ask("pf"))
        c.ask(f"z2,{syms['ticks']:x},4")
        c.ask("Z2,40000010,4")                                  # TIM2.SR written by its handler
        out["periph"] = c.ask("c")
        out["periph_pc"] = le32(c.ask("pf"))
        out["sr_held"] = le32(c.ask("m40000010,4"))
        out["step"] = c.ask("vCont;s:1")
        out["step_pc"] = le32(c.ask("pf"))
        c.ask("z2,40000010,4")
        c.ask("D")
    sim, out = session(script)
    syms, image = sim.firmware.symbols, sim.firmware.image
    half = lambda a: int.from_bytes(sim.firmware.core.read(a, 2), "little")
    assert out["ram"] == f"T05watch:{syms['ticks']:x};"
    assert image.function(out["ram_pc"]) == "SysTick_Handler" and _is_str_immediate_t1(half(out["ram_pc"]))
    assert out["again_pc"] == out["ram_pc"]
    assert out["periph"] == "T05watch:40000010;"
    assert image.function(out["periph_pc"]) == "TIM2_IRQHandler" and _is_str_immediate_t1(half(out["periph_pc"]))
    # the store to SR was made once, at the watchpoint (UIF cleared), and the step retires it from
    # its record: PC on to the next instruction, SR as the store left it
    assert out["sr_held"] & 1 == 0
    assert out["step"] == "T05" and out["step_pc"] == out["periph_pc"] + 2


def test_ctrl_c_halts_a_running_target_and_kill_ends_the_run():
    def script(c, syms, out):
        c.send("c")
        c.interrupt()
        out["stop"] = c.recv()
        assert out["stop"] == "T02"
        c.send("vKill;1")
        out["kill"] = c.recv()
    with pytest.raises(DebuggerKill):
        session(script, duration="10s")


def test_port_in_use_is_one_clear_error():
    busy = socket.socket()
    busy.bind(("127.0.0.1", 0))
    busy.listen(1)
    try:
        sim = mcusim.load("nucleo-f746", firmware=TICKS)
        with pytest.raises(mcusim.errors.ConfigError, match="cannot listen"):
            GdbServer(sim, busy.getsockname()[1])
    finally:
        busy.close()


@pytest.mark.skipif(shutil.which("gdb-multiarch") is None, reason="gdb-multiarch is not installed")
def test_gdb_multiarch_batch_session(tmp_path):
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    run = subprocess.Popen([sys.executable, "-m", "mcusim", "run", "nucleo-f746", "--firmware", TICKS,
                            "--gdb", str(port), "--duration", "50ms", "-q"],
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert "waiting for gdb" in run.stderr.readline()    # it listens (a probe would be taken for gdb)
        gdb = subprocess.run(
            ["gdb-multiarch", "-batch", "-nx", "-ex", "set pagination off", "-ex", f"file {TICKS}",
             "-ex", f"target extended-remote :{port}", "-ex", "info registers pc",
             "-ex", "break SysTick_Handler", "-ex", "continue", "-ex", "print ticks",
             "-ex", "set $s5 = 2.5", "-ex", "print $s5",
             "-ex", "stepi", "-ex", "info registers xpsr", "-ex", "delete",
             "-ex", "watch tim2_count", "-ex", "continue", "-ex", "delete", "-ex", "detach"],
            check=False, capture_output=True, text=True, timeout=120)
        out = gdb.stdout
        assert "<Reset_Handler>" in out
        assert "Breakpoint 1, SysTick_Handler" in out
        assert "$1 = 0" in out                            # the first tick, before its increment
        assert "$2 = 2.5" in out                          # s5 (half of d2) through the vfp feature
        assert "xpsr           0x100000f" in out          # IPSR 15: SysTick
        old, new = map(int, re.search(r"Old value = (\d+)\nNew value = (\d+)", out).groups())
        assert new == old + 1
    finally:
        stdout, stderr = run.communicate(timeout=120)
    assert run.returncode == 0, stderr
    assert "/ticks = 49" in stdout                        # detached, the run went on to its end
