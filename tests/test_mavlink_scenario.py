"""MAVLink in scenario files: the ``mavlink`` action and ``[[expect]] mavlink = ...``
(mcusim/scenario/mavlink.py), checked on the EDU-CIAA bench (no motor modules)."""

import pytest

from mcusim.cli import main
from mcusim.scenario import load_scenario, run_scenario

HEAD = '[scenario]\nboard = "ciaa-edu"\nduration = "300ms"\n'


def _write(tmp_path, body, head=HEAD):
    p = tmp_path / "s.toml"
    p.write_text(head + body)
    return p


# arm at 250 ms: refused (no motor modules), and two expectations of the answer
ARM = """
[[at]]
time = "250ms"
mavlink = { message = "COMMAND_LONG", target_system = 1, command = 400, param1 = 1 }

[[expect]]
name = "arming failed: no motor modules"
mavlink = "COMMAND_ACK"
fields = { command = 400, result = 4 }

[[expect]]
name = "not accepted"
mavlink = "COMMAND_ACK"
fields = { command = 400, result = 0 }
"""


def test_a_sent_command_is_answered_and_the_expectation_sees_the_answer_with_its_time(tmp_path):
    p = _write(tmp_path, ARM + """
[[expect]]
name = "nothing before it was sent"
time = "240ms"
mavlink = "COMMAND_ACK"

[[expect]]
name = "a heartbeat after 260 ms"
after = "260ms"
mavlink = "HEARTBEAT"
""")
    _, sc = run_scenario(load_scenario(p))
    ok = [r.passed for r in sc.results]
    assert ok == [True, False, False, False]      # one heartbeat a second: none after 260 ms
    t = float(sc.results[0].got.split()[2])
    assert 0.25 + 45 * 10 / 57600 < t < 0.3          # after the 45-byte command's frames at 57600 baud
    assert sc.results[1].got == "1 received, none matched; last: command=400, result=4"
    assert sc.results[3].got == "not received"
    assert any(text.startswith("mavlink COMMAND_LONG") for _, text in sc.log)


def test_float_fields_compare_as_float32_or_within_tol(tmp_path):
    p = _write(tmp_path, """
[[at]]
time = "250ms"
mavlink = { message = "PARAM_REQUEST_READ", target_system = 1, param_id = "BATT_LOW_V", param_index = -1 }

[[expect]]
mavlink = "PARAM_VALUE"
fields = { param_id = "BATT_LOW_V", param_value = 11.9 }

[[expect]]
mavlink = "PARAM_VALUE"
fields = { param_value = 11.8 }
tol = 0.11
""")
    _, sc = run_scenario(load_scenario(p))
    assert [r.passed for r in sc.results] == [True, True]


@pytest.mark.parametrize("body, message", [
    ('[[at]]\ntime = "1ms"\nmavlink = { message = "NO_SUCH" }\n', "'NO_SUCH' is not a MAVLink message"),
    ('[[at]]\ntime = "1ms"\nmavlink = { message = "HEARTBEAT", speed = 3 }\n', "HEARTBEAT has no field 'speed'"),
    ('[[at]]\ntime = "1ms"\nmavlink = { message = "HEARTBEAT", type = 300 }\n', "from 0 to 255 (uint8_t)"),
    ('[[at]]\ntime = "1ms"\nmavlink = { message = "PARAM_SET", param_id = "A_NAME_LONGER_THAN_16" }\n',
     "at most 16 bytes"),
    ('[[at]]\ntime = "1ms"\nmavlink = { type = 1 }\n', "expected a table { message ="),
    ('[[expect]]\nmavlink = "COMMAND_ACK"\nfields = { result = "yes" }\n', "expected a whole number"),
    ('[[expect]]\nmavlink = "COMMAND_ACK"\nequals = 1\n', "unknown key 'equals'"),
])
def test_a_mavlink_mistake_in_a_scenario_is_one_line_with_file_and_line_and_exit_2(tmp_path, capsys, body, message):
    p = _write(tmp_path, body)
    assert main(["run", "ciaa-edu", "--scenario", str(p)]) == 2
    err = capsys.readouterr().err
    assert message in err and f"{p}:" in err and "Traceback" not in err


def test_mavlink_scenario_on_a_board_without_mavlink_is_a_usage_error(tmp_path, capsys):
    p = _write(tmp_path, '[[at]]\ntime = "1ms"\nmavlink = { message = "HEARTBEAT" }\n',
               head='[scenario]\nduration = "10ms"\n')
    assert main(["run", "pro-mini", "--scenario", str(p)]) == 2
    assert "pro-mini runs no firmware with a MAVLink link" in capsys.readouterr().err


def test_the_mcusim_mavlink_fixture_gives_a_ground_station_on_the_firmwares_port(mcusim_sim, mcusim_mavlink):
    sim = mcusim_sim("ciaa-edu")
    gcs = mcusim_mavlink(sim, heartbeat_hz=0)
    hb = gcs.recv_match("HEARTBEAT", timeout="50ms")
    assert (hb.type, hb.get_srcSystem()) == (10, 1) and gcs.endpoint.usart is sim.mcu.periph["USART3"]
    sim.run(seconds="1.2s")
    assert sim.firmware.link.gcs_tick is None            # heartbeat_hz=0: the GCS sent none


def test_the_python_examples_of_docs_mavlink_run(mcusim_sim, mcusim_mavlink, capsys):
    import re
    from pathlib import Path
    text = (Path(__file__).resolve().parent.parent / "docs" / "mavlink.md").read_text()
    blocks = re.findall(r"```python\n(.*?)```", text, re.DOTALL)
    assert len(blocks) == 2
    for block in blocks:
        ns: dict = {}
        exec(compile(block, "docs/mavlink.md", "exec"), ns)     # noqa: S102 (the doc's own examples)
        for name, fn in ns.items():
            if name.startswith("test_"):
                fn(mcusim_sim, mcusim_mavlink)
    out = capsys.readouterr().out
    assert out.startswith("10 0 1\n") and "PARAM_VALUE {param_id : BATT_LOW_V" in out


def test_a_companion_heartbeat_from_system_1_component_191_counts_as_the_ground_station(mcusim_sim, mcusim_mavlink):
    """mavros takes the vehicle's system id and component 191 (ONBOARD_COMPUTER) by default."""
    sim = mcusim_sim("ciaa-edu")
    mcusim_mavlink(sim, system=1, component=191, heartbeat_hz=10)
    sim.run(seconds="0.25s")
    assert sim.firmware.link.gcs_tick is not None


def test_a_mavlink_expectation_that_saw_other_values_says_how_many_came_and_what_the_last_held(tmp_path):
    p = _write(tmp_path, """
[[at]]
time = "250ms"
mavlink = { message = "COMMAND_LONG", target_system = 1, command = 400, param1 = 1 }

[[expect]]
name = "armed"
mavlink = "COMMAND_ACK"
fields = { command = 400, result = 0 }

[[expect]]
name = "the bank unmeasured at boot: a prefix of the ten voltages"
mavlink = "BATTERY_STATUS"
fields = { voltages = [65535] }

[[expect]]
name = "a bank of 1 mV"
mavlink = "BATTERY_STATUS"
fields = { voltages = [1] }
""")
    _, sc = run_scenario(load_scenario(p))
    r = sc.results
    assert r[0].got == "1 received, none matched; last: command=400, result=4" and not r[0].passed
    assert r[1].passed                          # [65535] was not padded to [65535, 0, 0, ...]
    assert r[2].got.startswith("1 received, none matched; last: voltages=[65535, 65535") and not r[2].passed


@pytest.mark.parametrize("when", ['after = "2s"', 'after = "300ms"\ntime = "200ms"'])
def test_an_after_past_the_time_or_the_end_of_the_run_is_a_scenario_error(tmp_path, capsys, when):
    p = _write(tmp_path, f"""
[[expect]]
mavlink = "HEARTBEAT"
{when}
""")
    assert main(["run", "ciaa-edu", "--scenario", str(p)]) == 2
    err = capsys.readouterr().err
    assert "is later than" in err and "Traceback" not in err


def test_an_expectation_sees_every_message_of_the_run_however_few_the_clients_log_keeps(tmp_path, monkeypatch):
    """The ground station's log keeps the recent messages only (mcusim.recent); an end-of-run
    expectation of a reply that came early, with the log trimmed many times since, still finds it,
    counts what came and shows the last (it watches the messages as they arrive)."""
    import mcusim.recent
    monkeypatch.setattr(mcusim.recent, "KEEP", 3)
    p = _write(tmp_path, ARM, head='[scenario]\nboard = "ciaa-edu"\nduration = "1.2s"\n')
    _, sc = run_scenario(load_scenario(p))
    assert sc._gcs.log.dropped > 20            # the reply left the log long before the end
    assert [r.passed for r in sc.results] == [True, False]
    assert 0.25 < float(sc.results[0].got.split()[2]) < 0.3
    assert sc.results[1].got == "1 received, none matched; last: command=400, result=4"
    assert not sc._gcs.watchers                 # each expectation stopped watching at its check
