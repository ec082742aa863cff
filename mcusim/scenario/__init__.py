"""Scenarios: a TOML file that scripts a run.

A scenario names the board it is meant for and the run's length, sets parameters at build
(``[set]``, the ``--set`` keys), lists timed actions (``[[at]]``: topic messages, load torque, a
hand turning a shaft, a periodic topic forwarder, injected faults), expectations checked at a time
or at the end (``[[expect]]``) and optional measurements (``[report]``). The format, every key and
the fault kinds are in ``docs/scenarios.md``; the examples are in ``scenarios/``.

    from mcusim.scenario import load_scenario, run_scenario
    sc = load_scenario("scenarios/step_response.toml")     # parse and check: ConfigError if wrong
    sim = sc.build()                                       # mcusim.load(sc.board, overrides=sc.overrides)
    sc.apply(sim)                                          # schedule actions and expectations
    sim.run(seconds=sc.duration)
    sc.results, sc.failed, sc.report

    sim, sc = run_scenario("scenarios/step_response.toml", duration="1s")   # all of the above

Every mistake raises :class:`~mcusim.errors.ConfigError` with one message
``<file>:<line>: <problem>``: the line of the offending key (or of its table's header). tomllib
gives no positions, so :class:`.source._Lines` finds them by scanning the source for table headers and
keys. Actions run as kernel events at their exact tick (``timebase.ticks(time)``; a time that is
not a whole number of base ticks is an error) at ``PRIO_INPUT``; expectations are checked after
everything else of their tick (``PRIO_OBSERVE + 1``), the end ones at the run's last tick.

The package: ``source`` (line numbers in the TOML text), ``check`` (checked values and names,
the file:line errors), ``actions`` and ``faults`` (the action and fault kinds, one class each, in
a table), ``expect`` (expectations and the follow report), ``model`` (:class:`Scenario`: parse,
build, apply) and ``entry`` (:func:`load_scenario`, :func:`run_scenario`, :func:`scenario_names`).
"""

from .entry import SCENARIO_DIR as SCENARIO_DIR
from .entry import load_scenario, run_scenario, scenario_names
from .expect import ExpectResult
from .model import Scenario

__all__ = ["ExpectResult", "Scenario", "load_scenario", "run_scenario", "scenario_names"]
