"""The engine comparison (tests/engine_compare.py): it reads a VCD real variable as the step
function it encodes, and it compares runs that fail as far as they got.

A VCD holds only the changes of a real variable. Two engines whose values agree to the last bit
but one (a motor current resting at its steady state) record changes at different samples; the
signals are still equal within the tolerance, and must compare equal. A real difference must not.
"""

from engine_compare import REL, _compare_values, differences, real_mismatch, scalar_mismatch
from hypothesis import given
from hypothesis import strategies as st


def test_last_bit_wiggles_recorded_at_different_samples_compare_equal():
    # the CI-sweep case: the reference's last changes at 104.9 and 105.0 ms, the fast engine's at
    # 104.85 and 104.95 ms, all within one ulp of 0.16606250969326630
    ref = [(0, 0.0), (104750, 0.1660625096932663), (104850, 0.1660625096932662), (104900, 0.1660625096932663), (105000, 0.1660625096932664)]
    fast = [(0, 0.0), (104750, 0.1660625096932663), (104800, 0.1660625096932663), (104850, 0.1660625096932664), (104950, 0.1660625096932665)]
    assert real_mismatch(ref, fast) is None


# (no subnormal values: a signal whose full scale is 5e-324 cannot be moved by a fraction of it)
@given(st.lists(st.floats(-10.0, 10.0, allow_subnormal=False), min_size=2, max_size=30), st.integers(0, 29),
       st.floats(1e-6, 1.0))
def test_a_difference_above_the_tolerance_at_any_sample_is_reported(values, k, rel):
    k %= len(values)
    a = [(t * 50, v) for t, v in enumerate(values)]
    full = max(abs(v) for v in values) or 1.0
    b = list(a)
    b[k] = (b[k][0], b[k][1] + 10 * REL * full + rel * full)
    assert real_mismatch(a, b) is not None
    assert real_mismatch(a, a) is None


def test_a_sample_only_one_engine_has_is_reported():
    assert real_mismatch([(0, 1.0)], [(50, 1.0)]) is not None


def test_runs_that_both_fail_are_compared_up_to_where_they_stopped(tmp_path):
    """A fault found during the run (the bridge's OCD output driving EN against the MCU: a
    contention, exit status 1) leaves .part traces; the comparison reads them instead of failing
    on the missing files, and both engines stop at the same tick with the same traces."""
    argv = ["nucleo-f746", "--duration", "20ms", "--set", "bridgeB.drive_en=true", "--set", "bridgeB.I_ocd=2",
            "--set", "/motor2/set_pos=30"]
    assert differences(tmp_path, argv) == []
    for engine in ("reference", "fast"):
        assert (tmp_path / engine / "t.vcd.part").exists() and not (tmp_path / engine / "t.json").exists()


def test_a_command_line_that_is_refused_does_not_compare_equal(tmp_path):
    """Both engines refuse a mistyped command line (exit status 2) and write nothing: that is not
    agreement, and a generated case with a typo must not pass as one."""
    problems = differences(tmp_path, ["nucleo-f746", "--duration", "1ms", "--set", "nosuch.key=1"])
    assert any("did not run" in p for p in problems), problems


def test_an_edge_one_base_tick_apart_is_reported_with_the_rounding_tie_mark():
    """As the adversarial hunt met it on the rover (base tick 1225.49 ps, times rounded to ps):
    still a difference, marked as the rounding tie it may be; other moves are not marked."""
    tick = lambda: 1e12 / 816e6
    ref = [(0, "0"), (524445001225, "1"), (524445100000, "0")]
    one = [(0, "0"), (524445000000, "1"), (524445100000, "0")]
    assert "rounding tie" in scalar_mismatch("mcm1.PD3", ref, one, tick)
    two = [(0, "0"), (524444997549, "1"), (524445100000, "0")]       # two ticks early
    assert "rounding tie" not in scalar_mismatch("mcm1.PD3", ref, two, tick)
    extra = one + [(524445200000, "1")]                             # an edge more
    assert "rounding tie" not in scalar_mismatch("mcm1.PD3", ref, extra, tick)
    level = [(0, "0"), (524445001225, "0"), (524445100000, "0")]     # another level
    assert "rounding tie" not in scalar_mismatch("mcm1.PD3", ref, level, tick)


def test_a_turn_in_place_compares_its_pose_residues_at_the_scale_of_the_wheels_travel():
    """Found on a generated rover run (lin = 0, ang = 0.5 rad/s, E-stop at 159 ms): x and y of a
    turn in place are rounding residues of the wheels' travel, -3.4e-23 m in one engine and -3.0e-20 m
    in the other, which a scale of |x|, |y| alone reported as a disagreement. |yaw| counts as a
    length (times 1 m); a real difference of a pose still shows."""
    ref = {"pose": {"x": -3.3550445645150804e-23, "y": 1.2e-22, "yaw": 0.0745}}
    fast = {"pose": {"x": -3.039154208385124e-20, "y": 1.1e-22, "yaw": 0.0745}}
    problems: list = []
    _compare_values("summary", ref, fast, problems)
    assert problems == []
    fast["pose"]["x"] = 1e-6                    # a millimetre's thousandth: a real difference
    _compare_values("summary", ref, fast, problems)
    assert problems and problems[0].startswith("summary.pose.x")
