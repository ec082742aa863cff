"""Properties of the OpenRover robot controller's kinematics and odometry (firmware/openrover_rcm).

Round-trip tolerance: every output of forward(inverse(v)) is a short sum (at most 6 wheels) of
products whose coefficients (1/r, L/r and the pseudo-inverse computed once in float64) carry a
relative error of a few ulp times the conditioning of the wheel matrix, which the strategies keep
below ~3 (omni mounting angles stay near an even spread). The error is thus a small multiple of
eps * S, with S = |vx| + |vy| + lever * |wz| the largest wheel-rim speed scale (lever = half the
effective track, L, or lx + ly): linear terms to within TOL_K * eps * S and wz to within
TOL_K * eps * S / lever. Measured worst case over 2e5 random cases: 2.8 eps * S; TOL_K = 32 leaves a
10x margin while still catching any wrong coefficient (which errs by O(S), not O(eps * S)).
Subnormal speeds (below 1e-300) underflow, hence a tiny absolute floor.
"""

import math
import sys

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from mcusim.fw.openrover_rcm.kinematics import (
    ELEMENTALL_COUNTS_PER_WHEEL_REV,
    ELEMENTALL_WHEEL_RADIUS,
    make_layout,
    saturate,
)
from mcusim.fw.openrover_rcm.odometry import Odometry, Unwrap16, max_poll_interval, wrap_angle

EPS = sys.float_info.epsilon
TOL_K = 32
UNDERFLOW = 1e-300     # absolute floor: a relative bound means nothing for subnormal speeds
TWO_PI = 2.0 * math.pi

MODERATE = settings(max_examples=50, deadline=None)

radius = st.floats(0.01, 1.0)
length = st.floats(0.03, 3.0)
speed = st.floats(-5.0, 5.0)
rate = st.floats(-10.0, 10.0)


@st.composite
def differential(draw):
    return make_layout("differential", wheel_radius=draw(radius), track_width=draw(length))


@st.composite
def skid_steer(draw):
    return make_layout("skid_steer", wheel_radius=draw(radius), track_width=draw(length),
                       chi=draw(st.floats(1.0, 4.0)))


@st.composite
def omni(draw):
    n = draw(st.integers(3, 6))
    offset = draw(st.floats(-180.0, 180.0))
    jitter = draw(st.lists(st.floats(-60.0 / n, 60.0 / n), min_size=n, max_size=n))
    angles = [offset + 360.0 * i / n + j for i, j in enumerate(jitter)]
    return make_layout("omni", wheel_radius=draw(radius), wheel_distance=draw(length), angles_deg=angles)


@st.composite
def mecanum(draw):
    return make_layout("mecanum", wheel_radius=draw(radius), lx=draw(length), ly=draw(length))


nonholonomic = st.one_of(differential(), skid_steer())
holonomic = st.one_of(omni(), mecanum())
any_layout = st.one_of(nonholonomic, holonomic)


def lever(lay):
    if lay.kind in ("differential", "skid_steer"):
        return 0.5 * lay.b_eff
    if lay.kind == "omni":
        return lay.wheel_distance
    return lay.lx + lay.ly


def angle_diff(a, b):
    return abs(math.remainder(a - b, TWO_PI))


# ---- kinematics -----------------------------------------------------------------------------


@settings(max_examples=150, deadline=None)
@given(any_layout, speed, speed, rate)
def test_forward_of_inverse_is_the_identity_for_every_layout(lay, vx, vy, wz):
    if not lay.holonomic:
        vy = 0.0
    out = lay.forward(lay.inverse(vx, vy, wz))
    assert len(lay.inverse(vx, vy, wz)) == lay.wheels
    s = abs(vx) + abs(vy) + abs(wz) * lever(lay)
    tol = TOL_K * EPS * s + UNDERFLOW
    assert abs(out[0] - vx) <= tol
    assert abs(out[1] - vy) <= tol
    assert abs(out[2] - wz) <= tol / lever(lay)
    if not lay.holonomic:
        assert out[1] == 0.0


@MODERATE
@given(skid_steer(), speed, rate)
def test_skid_steer_gives_both_wheels_of_a_side_the_same_speed(lay, vx, wz):
    fl, fr, rl, rr = lay.inverse(vx, 0.0, wz)
    assert fl == rl and fr == rr
    # and the side speeds are those of a differential drive with the effective track chi * B
    diff = make_layout("differential", wheel_radius=lay.r, track_width=lay.chi * lay.track_width)
    assert (fl, fr) == pytest.approx(diff.inverse(vx, 0.0, wz), rel=1e-15, abs=1e-12)


@MODERATE
@given(skid_steer(), st.floats(-5.0, 5.0), st.floats(-5.0, 5.0), st.floats(-5.0, 5.0))
def test_skid_steer_forward_averages_each_side(lay, left, right, dev):
    # a slip between front and rear wheels of one side cancels in the side average
    a = lay.forward((left + dev, right - dev, left - dev, right + dev))
    b = lay.forward((left, right, left, right))
    assert a == pytest.approx(b, rel=1e-12, abs=1e-12)
    assert b[2] == pytest.approx(lay.r * (right - left) / (lay.chi * lay.track_width), rel=1e-12, abs=1e-12)


@MODERATE
@given(nonholonomic, speed, speed.filter(lambda v: v != 0.0), rate)
def test_differential_and_skid_steer_inverse_reject_sideways_velocity(lay, vx, vy, wz):
    with pytest.raises(ValueError, match="sideways"):
        lay.inverse(vx, vy, wz)


@MODERATE
@given(st.lists(st.floats(-100.0, 100.0), min_size=1, max_size=6), st.floats(0.1, 50.0))
def test_saturate_keeps_the_ratio_between_wheels_and_caps_the_peak(speeds, w_max):
    out = saturate(speeds, w_max)
    peak = max(abs(w) for w in speeds)
    assert len(out) == len(speeds)
    assert max(abs(w) for w in out) <= w_max
    if peak <= w_max:
        assert out == tuple(speeds)
        return
    assert max(abs(w) for w in out) == pytest.approx(w_max, rel=4 * EPS)
    for w, o in zip(speeds, out):
        # o / w == w_max / peak for every wheel: same factor, same signs, same curvature
        assert abs(o * peak - w * w_max) <= 4 * EPS * peak * w_max
        assert o * w >= 0.0                    # no wheel changes direction


@MODERATE
@given(skid_steer(), st.floats(0.1, 2.0), rate, st.floats(1.0, 20.0))
def test_saturate_preserves_the_commanded_curvature(lay, vx, wz, w_max):
    out = saturate(lay.inverse(vx, 0.0, wz), w_max)
    v2, _, wz2 = lay.forward(out)
    assert wz2 * vx == pytest.approx(wz * v2, rel=1e-12, abs=1e-12)


def test_layout_sign_conventions():
    d = make_layout("differential", wheel_radius=0.1, track_width=0.5)
    assert d.inverse(1.0, 0.0, 0.0) == (10.0, 10.0)
    wl, wr = d.inverse(0.0, 0.0, 1.0)             # CCW: left wheel back, right forward
    assert wl < 0 < wr
    m = make_layout("mecanum", wheel_radius=0.1, lx=0.2, ly=0.3)
    fl, fr, rl, rr = m.inverse(0.0, 1.0, 0.0)     # strafe left: FL, RR back; FR, RL forward
    assert fl < 0 and rr < 0 and fr > 0 and rl > 0
    fl, fr, rl, rr = m.inverse(0.0, 0.0, 1.0)
    assert fl < 0 and rl < 0 and fr > 0 and rr > 0
    o = make_layout("omni", wheel_radius=0.05, wheel_distance=0.2)   # 90, 210, 330 degrees
    w1, w2, w3 = o.inverse(1.0, 0.0, 0.0)
    assert w1 == pytest.approx(-20.0) and w2 == pytest.approx(10.0) and w3 == pytest.approx(10.0)
    assert o.inverse(0.0, 0.0, 1.0) == pytest.approx((4.0, 4.0, 4.0))


@pytest.mark.parametrize("kind, geometry, name", [
    ("differential", {"wheel_radius": 0.0, "track_width": 0.5}, "wheel_radius"),
    ("differential", {"wheel_radius": 0.1, "track_width": -0.5}, "track_width"),
    ("differential", {"wheel_radius": 0.1, "track_width": math.nan}, "track_width"),
    ("skid_steer", {"wheel_radius": 0.195, "track_width": 0.6, "chi": 0.9}, "chi"),
    ("omni", {"wheel_radius": 0.05, "wheel_distance": 0.0}, "wheel_distance"),
    ("omni", {"wheel_radius": 0.05, "wheel_distance": 0.2, "angles_deg": [0, 120, 360]}, "angles_deg"),
    ("omni", {"wheel_radius": 0.05, "wheel_distance": 0.2, "angles_deg": [0, 180]}, "angles_deg"),
    ("mecanum", {"wheel_radius": 0.05, "lx": 0.2, "ly": -1}, "ly"),
    ("mecanum", {"wheel_radius": 0.05, "lx": 0.2}, "ly"),
    ("mecanum", {"wheel_radius": 0.05, "lx": 0.2, "ly": 0.2, "track_width": 1}, "track_width"),
    ("tank", {"wheel_radius": 0.05}, "tank"),
])
def test_invalid_geometry_is_rejected_naming_the_parameter(kind, geometry, name):
    with pytest.raises(ValueError, match=name):
        make_layout(kind, **geometry)


def test_saturate_rejects_a_non_positive_limit():
    with pytest.raises(ValueError, match="w_max"):
        saturate((1.0, 2.0), 0.0)


# ---- 16-bit unwrapping ----------------------------------------------------------------------


@MODERATE
@given(st.integers(-(1 << 40), 1 << 40), st.lists(st.integers(-32767, 32767), max_size=300))
def test_unwrap16_reproduces_the_true_count_over_a_random_walk(start, steps):
    u = Unwrap16(start)
    true = start
    for step in steps:
        true += step
        assert u.update(true & 0xFFFF) == true


@MODERATE
@given(st.lists(st.sampled_from([32767, -32767, 32000, -32000, 1, -1]), min_size=1, max_size=200))
def test_unwrap16_follows_fast_walks_across_the_wrap_from_reset(steps):
    u = Unwrap16()
    true = 0
    for step in steps:
        true += step
        assert u.update(true & 0xFFFF) == true


def test_unwrap16_first_read_is_relative_to_the_module_reset_count_and_range_is_checked():
    assert Unwrap16().update(0xFFFF) == -1
    with pytest.raises(ValueError):
        Unwrap16().update(65536)


def test_elementall_poll_interval_is_0_78_s_at_half_a_metre_per_second():
    cps = 0.5 / (TWO_PI * ELEMENTALL_WHEEL_RADIUS) * ELEMENTALL_COUNTS_PER_WHEEL_REV
    assert cps == pytest.approx(41.79e3, rel=1e-3)
    t = max_poll_interval(0.5, ELEMENTALL_WHEEL_RADIUS, ELEMENTALL_COUNTS_PER_WHEEL_REV)
    assert t == pytest.approx(0.784, abs=1e-3)


# ---- odometry -------------------------------------------------------------------------------

cpr = st.sampled_from([ELEMENTALL_COUNTS_PER_WHEEL_REV, 2048, 4096 * 30, 360, 1000])


def counts_for(draw, lay, c, metres):
    """A count within +-``metres`` of rim travel: the 1e-12 bounds hold up to ~1 km (eps * 1 km =
    2.2e-13 m per rounding), and a single update of that size is already far beyond real polling."""
    top = int(metres / (TWO_PI * lay.r) * c)
    return draw(st.integers(-top, top))


@MODERATE
@given(nonholonomic, cpr, st.data(), st.integers(1, 8))
def test_odometry_straight_run_of_n_counts_gives_x_n_over_cpr_times_circumference(lay, c, data, chunks):
    n = counts_for(data.draw, lay, c, 500.0)
    odo = Odometry(lay, c)
    for i in range(1, chunks + 1):
        x, y, yaw = odo.update([n * i // chunks] * lay.wheels)
    assert abs(x - n / c * TWO_PI * lay.r) <= 1e-12
    assert y == 0.0 and yaw == 0.0


@MODERATE
@given(nonholonomic, cpr, st.data())
def test_odometry_in_place_rotation_gives_yaw_r_dphi_difference_over_effective_track(lay, c, data):
    n = counts_for(data.draw, lay, c, 100 * math.pi * lay.b_eff)      # up to 100 turns
    odo = Odometry(lay, c)
    left, right = -n, n
    x, y, yaw = odo.update([left, right] * (lay.wheels // 2))
    dphi_l, dphi_r = left / c * TWO_PI, right / c * TWO_PI
    assert x == 0.0 and y == 0.0
    assert angle_diff(yaw, lay.r * (dphi_r - dphi_l) / lay.b_eff) <= 1e-12
    assert -math.pi < yaw <= math.pi


@MODERATE
@given(holonomic, cpr, st.data())
def test_odometry_in_place_rotation_for_omni_and_mecanum(lay, c, data):
    n = counts_for(data.draw, lay, c, 200 * math.pi * lever(lay))      # up to 100 turns
    odo = Odometry(lay, c)
    dphi = n / c * TWO_PI
    if lay.kind == "omni":
        counts, expected = [n] * lay.wheels, lay.r * dphi / lay.wheel_distance
    else:
        counts, expected = [-n, n, -n, n], lay.r * dphi / (lay.lx + lay.ly)
    x, y, yaw = odo.update(counts)
    assert abs(x) <= 1e-12 and abs(y) <= 1e-12
    assert angle_diff(yaw, expected) <= 1e-12


@MODERATE
@given(mecanum(), cpr, st.data())
def test_odometry_mecanum_strafe_moves_along_y(lay, c, data):
    n = counts_for(data.draw, lay, c, 500.0)
    x, y, yaw = Odometry(lay, c).update([-n, n, n, -n])
    assert abs(x) <= 1e-12 and abs(yaw) <= 1e-12
    assert abs(y - lay.r * n / c * TWO_PI) <= 1e-12


@settings(max_examples=80, deadline=None)
@given(any_layout, st.data(), st.integers(2, 200), st.floats(-50, 50), st.floats(-50, 50),
       st.floats(-math.pi, math.pi))
def test_odometry_arc_in_many_steps_equals_one_step(lay, data, m, x0, y0, yaw0):
    c = 2048
    step = data.draw(st.lists(st.integers(-3000, 3000), min_size=lay.wheels, max_size=lay.wheels))
    start = data.draw(st.lists(st.integers(-(1 << 40), 1 << 40), min_size=lay.wheels,
                               max_size=lay.wheels))
    fine = Odometry(lay, c, counts=start, pose=(x0, y0, yaw0))
    coarse = Odometry(lay, c, counts=start, pose=(x0, y0, yaw0))
    for i in range(1, m + 1):
        pf = fine.update([s + i * d for s, d in zip(start, step)])
    pc = coarse.update([s + m * d for s, d in zip(start, step)])
    assert abs(pf[0] - pc[0]) <= 1e-9 and abs(pf[1] - pc[1]) <= 1e-9
    assert angle_diff(pf[2], pc[2]) <= 1e-9


@MODERATE
@given(differential(), st.integers(1, 4000), st.integers(-4000, 4000))
def test_odometry_arc_matches_the_circle_of_the_differential_drive(lay, dl, dr):
    # one update along a circle of radius R = (B/2)(dR + dL)/(dR - dL) about (0, R)
    c = 2048
    x, y, yaw = Odometry(lay, c).update([dl, dr])
    s = lay.r * (dl + dr) / 2 / c * TWO_PI
    th = lay.r * (dr - dl) / lay.b_eff / c * TWO_PI
    if th == 0.0:
        assert (x, y) == pytest.approx((s, 0.0), abs=1e-12)
        return
    rad = s / th
    assert x == pytest.approx(rad * math.sin(th), abs=1e-12)
    assert y == pytest.approx(rad * (1.0 - math.cos(th)), abs=1e-12)
    assert angle_diff(yaw, th) <= 1e-12


def test_wrap_angle_range():
    assert wrap_angle(-math.pi) == math.pi
    assert wrap_angle(math.pi) == math.pi
    assert wrap_angle(3 * math.pi / 2) == pytest.approx(-math.pi / 2)
