"""Cases where the fast engine once disagreed with the reference engine, found by an adversarial
review (tests/test_engine_fuzz_*.py generalise them). Each asserts that the two engines agree
(first difference reported) for the situation named."""

import pytest
from diff_net import compare as compare_net
from diff_plant import compare as compare_plant
from diff_tim import compare as compare_tim

from mcusim.engine.waveform import Waveform
from mcusim.kernel import Kernel
from mcusim.plant.bts7960 import Bts7960Bridge
from mcusim.plant.dcmotor import DcMotor
from mcusim.plant.l6206 import L6206Bridge
from mcusim.signals import Net
from mcusim.time import TimeBase


def test_down_counting_with_arr_lowered_below_cnt_runs_to_zero_as_the_reference():
    init = [("CR1", 16), ("ARR", 9), ("CCR1", 1), ("CCMR1", 0x60), ("CCER", 1), ("EGR", 1), ("CR1", 17)]
    for ops in ([(2, "w", "ARR", 3)], [(2, "w", "ARR", 3), (5, "r", "CNT", 0), (6, "r", "SR", 0)]):
        d, _, _ = compare_tim("TIM3", init, ops, 30)
        assert d is None, d


def test_frozen_mode_keeps_the_ocxref_of_the_waveform_at_the_switch():
    init = [("ARR", 1), ("CCR2", 1), ("CCMR1", 0x6060), ("CCER", 0x11), ("EGR", 1), ("CR1", 1)]
    for cyc in range(4):
        for rec in ("edges", "waves"):
            d, _, _ = compare_tim("TIM3", init, [(cyc, "w", "CCMR1", 0)], 12, rec)
            assert d is None, (cyc, rec, d)


def test_enabling_ccxie_or_uie_with_a_lazy_flag_due_raises_the_line_at_once():
    init = [("ARR", 9), ("RCR", 3), ("CCR1", 3), ("CCMR1", 0x60), ("CCER", 1), ("BDTR", 1 << 15), ("EGR", 1),
            ("SR", 0), ("CR1", 1)]
    for ops, n in (([(5, "w", "DIER", 2)], 40), ([(7, "w", "DIER", 2)], 40), ([(15, "w", "DIER", 1)], 80)):
        d, _, _ = compare_tim("TIM1", init, ops, n)
        assert d is None, d


def test_an_edge_listener_attached_mid_waveform_gets_the_next_edge():
    for arr, ccr, n, ats in ((1, 1, 8, (0, 1, 2, 3)), (9, 3, 30, (3, 5, 10, 15))):
        init = [("MODER", 2 << 12), ("AFRL", 2 << 24), ("ARR", arr), ("CCR1", ccr), ("CCMR1", 0x60),
                ("CCER", 1), ("EGR", 1), ("CR1", 1)]
        for la in ats:
            d, _, _ = compare_net(init, [], n, listen_at=la, sample=False)
            assert d is None, (la, d)


def test_a_pwm_pin_switched_to_open_drain_keeps_toggling():
    init = [("MODER", 2 << 12), ("AFRL", 2 << 24), ("PUPDR", 1 << 12), ("ARR", 9), ("CCR1", 3),
            ("CCMR1", 0x60), ("CCER", 1), ("EGR", 1), ("CR1", 1)]
    d, _, _ = compare_net(init, [(12, "w", "OTYPER", 1 << 6)], 60)
    assert d is None, d


def test_a_pwm_pin_released_to_floating_keeps_its_last_level():
    init = [("MODER", 2 << 12), ("AFRL", 2 << 24), ("ARR", 9), ("CCR1", 3), ("CCMR1", 0x60), ("CCER", 1),
            ("EGR", 1), ("CR1", 1)]
    d, _, _ = compare_net(init, [(15, "w", "MODER", 0), (16, "r", "IDR", 0)], 30, listen_at=10**6)
    assert d is None, d


def test_l6206_follows_pwm_of_different_periods_again_after_an_ocd_release():
    segs = {"in1": [(0, 1), (30000, (0, 10800, 5400))], "in2": [(0, 0), (30000, (0, 14400, 3600))],
            "en": [(0, 1)]}
    d, a, b = compare_plant(segs, 216000 * 3, bridge_kw={"I_ocd": 0.3}, samples=3000, enc=True)
    assert d is None, d
    assert a["trips"] == b["trips"]


def test_peak_current_of_an_underdamped_segment_is_its_true_maximum():
    """With a complex eigenvalue pair the current oscillates inside one segment; the peak tracked
    is its maximum over the segment (first two stationary points), not the value at whatever
    segment ends an engine happens to make (which made the engines' peaks differ)."""
    import math

    from mcusim.plant import pwl
    A = (-200.0, -7.3, 22000.0, -0.1)          # R/L small against K²/(L·J): underdamped
    eig = pwl.eig2(*A)
    assert eig[4]
    tr = pwl.affine2(eig, A, (8000.0, -300.0), (0.0, 0.0, 0.0))
    t_end = 0.02
    dense = max(abs(tr.eval(t_end * j / 20000)[0]) for j in range(20001))
    tracked = max([abs(tr.eval(t_end)[0])] + [abs(tr.eval(t)[0]) for t in tr.x1_extrema(t_end)])
    assert math.isclose(tracked, dense, rel_tol=1e-6) and tracked >= dense * (1 - 1e-12)


def test_a_stiction_change_mid_run_is_seen_by_the_cached_period_plans():
    """The fast engine caches each period's plan (its maps and guards) per drive, mode and motor
    parameters. At 6 % duty a stuck shaft's current rises towards 0.258 A, below the 0.45 A
    breakaway of tau_s = 5 mN·m; lowered to 2.6 mN·m (breakaway 0.236 A) at 0.5 ms, while the current
    is still rising and the shaft still stuck (the same mode, the same plan key but for tau_s), the
    shaft must break away about 1.2 ms later, as in the reference engine: a breakaway guard
    kept from the plan built before the change would never fire."""
    MS = 216000
    segs = {"in1": [(0, (0, 4320, 259))], "in2": [(0, 0)], "en": [(0, 1)]}
    changes = [(MS // 2 + 1234, {"tau_s": 2.6e-3})]
    d, a, _b = compare_plant(segs, 10 * MS, samples=1000, param_changes=changes)
    assert d is None, d
    moved = [s for s in a["state"] if s[0] < 3 * MS and s[2] > 0.0]
    assert moved, "the shaft should break away once tau_s is lowered"


def _l6206_rig(engine):
    """(kernel, nets in1/in2/en, motor): a default motor on an L6206 bridge, enabled, inputs low."""
    k = Kernel(TimeBase([216_000_000]), engine)
    nets = {n: Net(n) for n in ("in1", "in2", "en")}
    for n in nets.values():
        n.set("drv", 0)
    m = DcMotor(k, "m")
    L6206Bridge(k, m, nets["in1"], nets["in2"], nets["en"], "br")
    nets["en"].set("drv", 1)
    return k, nets, m


def _bts7960_rig(engine):
    """The same with a BTS7960 (IBT-2): RPWM as ``in1``, LPWM low, both enables high."""
    k = Kernel(TimeBase([216_000_000]), engine)
    nets = {n: Net(n) for n in ("in1", "lpwm", "r_en", "l_en")}
    for n in nets.values():
        n.set("drv", 0)
    m = DcMotor(k, "m")
    Bts7960Bridge(k, m, nets["in1"], nets["lpwm"], nets["r_en"], nets["l_en"], name="ibt2")
    nets["r_en"].set("drv", 1)
    nets["l_en"].set("drv", 1)
    return k, nets, m


@pytest.mark.parametrize("rig", [_l6206_rig, _bts7960_rig])
def test_a_waveform_republished_with_the_same_shape_leaves_the_motor_chunk_as_it_is(rig):
    """A timer whose preload waits for the next update event republishes its PWM waveform with the
    tick where it ends (TimerOne's duty written into OCR1A's buffer, HAL's CCR with preload); the
    bridge's drive is the same shape, so the motor keeps its chunk (no new segment) and its state
    is the one the reference engine gives."""
    MS = 216000
    states = {}
    for engine in ("reference", "fast"):
        k, nets, m = rig(engine)
        if engine == "fast":
            nets["in1"].set_wave("drv", Waveform(k, 0, 4320, 2000))
            k.run_until(5 * MS + 17)
            seg = m.segments
            nets["in1"].set_wave("drv", Waveform(k, 0, 4320, 2000, end=6 * MS))
            assert m.segments == seg
            k.run_until(6 * MS)
            nets["in1"].set_wave("drv", Waveform(k, 6 * MS, 4320, 2000))
            assert m.segments == seg
        else:
            w = Waveform(k, 0, 4320, 2000)
            nets["in1"].set("drv", 1)
            t = 0
            while True:
                t, lv = w.next_edge(t)
                if t > 8 * MS:
                    break
                k.at(t, nets["in1"].set, "drv", lv)
        k.run_until(8 * MS)
        states[engine] = (m.current, m.speed, m.angle)
    for a, b in zip(states["reference"], states["fast"]):
        assert abs(a - b) <= 1e-9 * max(abs(a), abs(b)), states


def test_a_shaft_held_just_below_breakaway_runs_in_whole_period_chunks_as_the_reference():
    """A position loop holds the shaft stuck with the current ripple peaking just below breakaway
    (the nucleo-f746 bench's hold: 442/4320 duty, 0.440 A mean). In a stuck piece the current is one
    exponential, so the breakaway guard is decided by its values at the piece ends; the derivative
    bound alone flagged every period there and the fast engine ran the hold piece by piece
    (~1700 segments in 20 ms). Both engines agree, and the fast one holds with a few chunks."""
    MS = 216000
    segs = {"in1": [(0, (0, 4320, 442))], "in2": [(0, 0)], "en": [(0, 1)]}
    d, a, b = compare_plant(segs, 20 * MS, samples=400)
    assert d is None, d
    assert a["state"][-1][2] == 0.0 and b["state"][-1][2] == 0.0     # still stuck at the end
    assert b["segments"] < 50, b["segments"]


def test_a_state_read_in_the_previous_chunk_after_set_params_uses_the_parameters_it_ran_with():
    """``state_at`` of a tick in the previous segment (the BTS7960's IS output reads one) gives the
    state the motor had there, whatever changed since: a fast-engine chunk builds its pieces'
    closed forms when they are read, and once built them with the parameters of the read, not those
    the chunk ran with. (The reference engine's previous segment is the last PWM piece only, so the
    tick, in an earlier period, is the fast engine's to answer.)"""
    MS = 216000
    k, nets, m = _l6206_rig("fast")
    nets["in1"].set_wave("drv", Waveform(k, 0, 4320, 2000))
    t1 = 5 * MS + 1000
    k.run_until(t1)
    probe = t1 - 3000      # the off-piece of the period before
    assert m._traj.kind == "chunk"
    before = m.state_at(probe)
    m.set_params(L=3e-3, K=0.02)
    assert m.state_at(probe) == before


def test_a_stuck_shaft_on_pieces_longer_than_the_electrical_time_constant_runs_in_chunks():
    """With 0.2 mH and 10 kHz PWM a piece lasts longer than L/R (τ·|λ| ≥ 1), where the derivative
    bound of the screening has no fixed point. A stuck piece needs none (its |i| peaks at an end,
    ω is held), so a shaft held by stiction there still runs in whole-period chunks (it ran piece
    by piece, ~600 segments in 20 ms), and agrees with the reference engine."""
    MS = 216000
    segs = {"in1": [(0, (0, 21600, 600))], "in2": [(0, 0)], "en": [(0, 1)]}
    d, a, b = compare_plant(segs, 20 * MS, motor_kw={"L": 2e-4}, samples=400)
    assert d is None, d
    assert a["state"][-1][2] == 0.0 and b["state"][-1][2] == 0.0     # stuck throughout
    assert b["segments"] < 50, b["segments"]


def test_a_constant_pwm_output_that_becomes_a_waveform_at_a_wrap_changes_once():
    """CCR1 goes from 0 (PWM mode 1: always inactive) to 30 through its preload: at the update
    event the output becomes a waveform. Its listeners (an H-bridge, which rebuilds the motor's
    segment at every change) are told once, with the waveform, not first of a constant high level
    and then of the waveform at the same tick; the edges are the reference engine's."""
    from tim_oracle import Rig
    init = [("ARR", 99), ("CCR1", 0), ("CCMR1", 0x68), ("CCER", 1), ("EGR", 1), ("CR1", 1)]
    d, _, _ = compare_tim("TIM3", init, [(150, "w", "CCR1", 30)], 600)
    assert d is None, d
    rig = Rig("TIM3", 108, engine="fast")
    k = rig.kernel
    told = []
    rig.tim.oc[1].listen(lambda p: told.append((k.now, p.value, p.wave)), waves=True)
    for reg, v in init:
        rig.w(reg, v)
    k.run_until(k.now + 150 * rig.P)
    told.clear()
    rig.w("CCR1", 30)
    k.run_until(k.now + 100 * rig.P)
    assert len(told) == 1, told
    assert told[0][1] == 1 and told[0][2] is not None


@pytest.mark.parametrize("board, motor", [("elementall", "mcm1.motor"), ("rover-diff", "left.motor")])
def test_a_hand_turn_on_a_battery_fed_wheel_closes_the_supply_account_of_the_segment_it_ends(tmp_path, board,
                                                                                          motor):
    """A hand turn re-sets the shaft speed every millisecond, on the battery's own step ticks. The
    fast engine rebuilds the motor once at the end of such a tick; the battery's step in between
    asks the bridge for the charge drawn, which it took from the segment that just ended (it
    stopped the run with "supply accounting lost a motor segment")."""
    from engine_compare import differences
    sc = tmp_path / "turn.toml"
    sc.write_text(f'[scenario]\nboard = "{board}"\nduration = "6ms"\n\n[[at]]\ntime = "0s"\n'
                  f'turn = {{ motor = "{motor}", angle = 0.5, over = "30ms" }}\n')
    assert differences(tmp_path, [board, "--scenario", str(sc)]) == []
