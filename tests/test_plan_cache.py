"""The fast engine's caches of period plans and piece flows (mcusim.plant.dcmotor_fast.SecondSight):
a value is kept only for a key that came before, least recently used dropped first, memory bounded.
What a cache holds never changes a result (test_engine_equality), only how often a plan is built."""

from collections import Counter

from hypothesis import given
from hypothesis import strategies as st

import mcusim
from mcusim.plant.dcmotor_fast import SecondSight


def _model(keys, limit):
    """What a second-sight LRU holds after ``keys`` were each looked up and, on a miss, put (the
    rule written out plainly: a list in use order, and every key seen within the last 4·limit
    first sights)."""
    kept, firsts = [], []
    for k in keys:
        if k in kept:
            kept.remove(k)
            kept.append(k)
        elif k in firsts:
            if len(kept) >= limit:
                kept.pop(0)
            kept.append(k)
        else:
            firsts.append(k)
            if len(firsts) > 4 * limit:
                firsts.pop(0)
    return kept


@given(keys=st.lists(st.integers(0, 40), max_size=300), limit=st.integers(1, 6))
def test_a_value_is_kept_from_the_second_sight_of_its_key_least_recently_used_dropped_first(keys, limit):
    cache = SecondSight(limit)
    for k in keys:
        if cache.get(k) is None:
            cache.put(k, ("built", k))
        assert len(cache) <= limit
    kept = _model(keys, limit)
    assert list(cache._d) == kept
    assert all(cache.get(k) == ("built", k) for k in kept)


def test_keys_seen_once_are_forgotten_after_four_times_the_limit_of_other_keys():
    cache = SecondSight(2)
    cache.put("a", 1)
    for k in range(8):
        cache.put(k, k)
    cache.put("a", 1)               # "a" left the memory of first sights: a first sight again
    assert cache.get("a") is None
    cache.put("a", 1)
    assert cache.get("a") == 1


def test_the_rover_at_speed_keeps_no_new_plan_and_the_promini_keeps_its_limit_cycle():
    """Every millisecond the rover's battery and body change each motor's supply voltage and load
    torque: once the wheels turn no plan key repeats, and no plan joins the cache. The pro-mini's
    velocity loop revisits its plans: the cache holds some and they are used."""
    rover = mcusim.load("elementall", overrides={"cmd_vel.linear": 0.5, "cmd_vel.angular": 0.2})
    rover.run(seconds=0.4)
    motors = [m["parts"]["motor"] for name, m in rover.members.items() if name.startswith("mcm")]
    kept = [list(m._plans._d) for m in motors]
    built = sum(m.segments for m in motors)
    rover.run(seconds=0.3)
    assert sum(m.segments for m in motors) - built > 1000
    assert [list(m._plans._d) for m in motors] == kept
    promini = mcusim.load("pro-mini", overrides={"velocity": 20})
    promini.run(seconds=1.0)
    assert len(promini.part("motor")._plans) > 0


def test_a_guessed_crossing_tick_is_taken_only_where_the_search_finds_that_tick():
    """After a rebuild the next encoder crossing is first checked at the tick the old trajectory
    had it (``PeriodicDrive._passive_at``: fired there and not one tick before). Whatever tick is
    guessed, the check either declines or gives what the full search gives: here the ticks around
    the true crossing, around the search's start, half-way and at the trajectory's end, on the
    rover's wheels at speed (in chunks and between them)."""
    rover = mcusim.load("elementall", overrides={"cmd_vel.linear": 0.5, "cmd_vel.angular": -0.3})
    rover.run(seconds=0.5)
    motors = [m["parts"]["motor"] for name, m in rover.members.items() if name.startswith("mcm")]
    taken = 0
    for _ in range(40):
        rover.run(seconds=0.0021)
        for m in motors:
            tr = m._traj
            after = rover.kernel.now - m._t0
            end = tr.periods * tr.plan.P if tr.kind == "chunk" else m._seg_end
            guards = [g for prov in m._providers if getattr(prov, "passive_guards", False)
                      for g in prov.plant_guards()]
            best, firing = m._first_passive(guards, after)
            b = after + 100 if best is None else best
            probes = {after - 1, after, after + 1, after + 2, (after + b) // 2, end - 1, end, end + 1}
            for n in probes | set(range(b - 3, b + 4)):
                got = m._passive_at(guards, after, end, n)
                if got is not None:
                    assert got == (best, firing)
                    taken += 1
    assert taken >= 40


def test_a_timer_update_that_moves_both_inputs_of_an_l6206_rebuilds_its_motor_once(monkeypatch):
    """Reversing, the nucleo-f746's timer update republishes both inputs of a bridge in one event.
    The L6206 hands the change to its motor when that event returns, with both pins moved: one
    plan per tick and motor (52 ticks of its first second had two, the first thrown away). The
    engines' results stay equal (test_engine_equality: the nucleo bench command and scenarios)."""
    from mcusim.plant import dcmotor

    sim = mcusim.load("nucleo-f746", overrides={"/motor1/set_pos": 9.42478, "/motor2/set_pos": -1.5708})
    per_tick = Counter()
    rebuild = dcmotor.DcMotor._rebuild

    def counted(self):
        per_tick[(sim.kernel.now, self.name)] += 1
        return rebuild(self)
    monkeypatch.setattr(dcmotor.DcMotor, "_rebuild", counted)
    sim.run(seconds=1.0)
    assert len(per_tick) > 500
    assert max(per_tick.values()) == 1
